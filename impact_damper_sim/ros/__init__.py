"""ROS 2 adapters: the only sub-package that imports rclpy.

Importing it asks OpenBLAS for one thread (unless the environment says otherwise): the nodes'
matrices are small, and idle BLAS threads spin on cores the stepping thread and DDS need.
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
