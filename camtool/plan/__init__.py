"""Redundant-arm planning: CWLN IK (cwln.py) and the seed strategy (strategy.py)."""
from .strategy import plan_path

__all__ = ["plan_path"]
