"""argparse value types shared by the command-line tools: a bad value is a usage error
(exit code 2, a message saying what was expected), never a traceback."""
import argparse
import math
import re

from sela_ros.core.learning.gp import MAX_SIGMA, MIN_SIGMA
from sela_ros.experiments.baselines import METHODS

#: Default std (m) of the noise on observed positions in both experiments. The paper writes
#: "sigma^2 = 0.01"; read literally that is a std of 0.1 m (as large as a toy step and as the
#: goal tolerance), and its claims ("almost optimal" steps) hold with a std of 0.01 m
#: instead (docs/toy_results.md). `--noise-std 0.1` runs the literal reading.
DEFAULT_NOISE_STD = 0.01
#: The largest std (m) of that noise: the sim_bridge node's ``observation.noise_std`` range.
#: Beyond it a position says nothing of a gait (the fastest moves 0.7 m) and overflows.
MAX_NOISE_STD = 1.0
NOISE_HELP = ("std (m) of the noise on observed positions, 0 to 1 (default %(default)s; the "
              "paper's 'sigma^2 = 0.01' read literally is 0.1, see docs/toy_results.md)")


def non_negative_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f'expected a finite number >= 0, got {text!r}')
    return value


def positive_float(text):
    value = non_negative_float(text)
    if value == 0:
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {text!r}')
    return value


def noise_std(text):
    """``--noise-std``: a std (m) in [0, :data:`MAX_NOISE_STD`]."""
    value = non_negative_float(text)
    if value > MAX_NOISE_STD:
        raise argparse.ArgumentTypeError(
            f'expected a std of at most {MAX_NOISE_STD:g} m (the sim_bridge node\'s '
            f'observation.noise_std range), got {text!r}')
    return value


def kernel_sigma(text):
    """A GP kernel length in [``gp.MIN_SIGMA``, ``gp.MAX_SIGMA``], the node's range: a shorter
    one underflows (a division by zero, NaN predictions)."""
    value = non_negative_float(text)
    if not MIN_SIGMA <= value <= MAX_SIGMA:
        raise argparse.ArgumentTypeError(
            f'expected a kernel length in [{MIN_SIGMA:g}, {MAX_SIGMA:g}] '
            f'(on normalised descriptors), got {text!r}')
    return value


def _integer(text, what='an integer'):
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected {what}, got {text!r}') from None


def positive_int(text):
    value = _integer(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected an integer >= 1, got {value}')
    return value


def non_negative_int(text):
    value = _integer(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f'expected an integer >= 0, got {value}')
    return value


def seed(text):
    value = _integer(text, 'an integer seed')
    if value < 0:
        raise argparse.ArgumentTypeError(f'expected a seed >= 0, got {value}')
    return value


#: The largest seed a node's ``seed`` parameter takes (rclpy's integer range for it).
NODE_SEED_MAX = 2**31 - 1


def node_seed(text):
    """A seed that a node's ``seed`` parameter takes: 0 to :data:`NODE_SEED_MAX`."""
    value = seed(text)
    if value > NODE_SEED_MAX:
        raise argparse.ArgumentTypeError(f'expected a seed <= {NODE_SEED_MAX}, got {value}')
    return value


def method_list(text):
    """Comma-separated method names, each once (a repeat is dropped: it would run twice)."""
    names = list(dict.fromkeys(n.strip() for n in text.split(',') if n.strip()))
    if not names:
        raise argparse.ArgumentTypeError(
            f'expected at least one method, got {text!r}; choose from {", ".join(METHODS)}')
    unknown = [n for n in names if n not in METHODS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f'unknown method(s) {", ".join(unknown)}; choose from {", ".join(METHODS)}')
    return names


def goal(text):
    """``X,Y`` in metres."""
    try:
        values = [float(v) for v in text.split(',')]
    except ValueError:
        values = []
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f'expected the goal as X,Y (metres), got {text!r}')
    return values


def damage(text):
    """A damage spec (sim_bridge.damage); returns its canonical form."""
    from sim_bridge.damage import DamageSpecError, parse_damage

    try:
        return parse_damage(text).canonical()
    except DamageSpecError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def take_negative_points(parser: argparse.ArgumentParser) -> None:
    """Let ``--goal -2,1.5`` and ``--goals 2,2 -2,1.5`` through: argparse before Python
    3.13 takes a value that starts with '-' and is not a plain number for an option (3.13
    already takes anything starting with a negative number as a value)."""
    if hasattr(parser, '_negative_number_matcher'):
        parser._negative_number_matcher = re.compile(r'^-\.?\d')
