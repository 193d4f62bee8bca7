"""Map building (quality diversity): archives, emitters, the MAP-Elites loop, checkpoints
and executors."""
