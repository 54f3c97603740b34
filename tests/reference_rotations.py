"""Elementary rotation matrices written out in NumPy: independent references for tests."""
import numpy as np


def rot_x(a):
    """Rotation by ``a`` (rad) about x."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a):
    """Rotation by ``a`` (rad) about y."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
