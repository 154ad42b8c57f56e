"""Rebuild the shipped allowed-collision matrices of the built-in robots
(camtool/collision/data/acm_<robot>.json) after a robot's geometry changes."""
from camtool.collision.acm import write_shipped_acms

if __name__ == "__main__":
    for name, n in write_shipped_acms().items():
        print(name, n, "allowed pairs")
