"""The plain-matrix kinematic chain of closed-form IK and the capsule checks (``robots/ik_common.py``)."""
import numpy as np
import pytest

from camtool.robots import get_robot
from camtool.robots.ik_common import Chain


@pytest.mark.parametrize("name", ["irb2400", "seed8", "sia20"])
def test_frames_of_many_rows_are_the_frames_of_each_bit_for_bit(name):
    robot = get_robot(name)
    chain = Chain(robot)
    Q = np.random.default_rng(2).uniform(robot.limits.lower, robot.limits.upper, (50, robot.dof))
    many = chain.frames_many(Q)
    assert many.shape == (50, robot.dof + 1, 4, 4)
    for q, F in zip(Q, many):
        assert np.array_equal(np.array(chain.frames(q)), F)
    assert np.allclose(many[:, -1], [robot.fk(q) for q in Q], atol=1e-9)   # and the flange is Pinocchio's
