"""Helpers a shader in tests/test_shader_python.py imports from another module (plain Python)."""
from math import sqrt

QUARTER = 0.25


def eighth(x):
    return 0.5 * QUARTER * x


def imported_helper(x):
    return sqrt(QUARTER) + x
