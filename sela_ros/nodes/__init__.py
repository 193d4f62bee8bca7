"""The three learning-side ROS 2 nodes and what they share: conversions, parameters, QoS.

Imported before numpy by every node's entry point: each node process runs one BLAS thread
unless the user's environment sets its own (:func:`sela_ros.single_blas_thread`).
"""
from sela_ros import single_blas_thread

single_blas_thread()
