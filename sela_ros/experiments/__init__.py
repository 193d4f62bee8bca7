"""Experiments that reproduce the paper's figures (``sela-experiment``); ROS-free."""
