"""camtool.robots.joint_frames: many configurations' joint frames at once, the same as Pinocchio's one by one."""
import numpy as np
import pytest

from camtool.robots import get_robot
from camtool.robots.joint_frames import JointFrames, joint_frames_mm


@pytest.mark.parametrize("name", ["seed8", "irb2400", "sia20"])
def test_batched_frames_are_pinocchios(name):
    robot = get_robot(name)
    frames = JointFrames(robot)
    assert frames.batched
    lo, hi = robot.limits.lower, robot.limits.upper
    Q = lo + np.random.default_rng(3).random((200, robot.dof)) * (hi - lo)
    F = frames(Q)
    assert F.shape == (200, robot.dof, 4, 4)
    one_by_one = np.array([joint_frames_mm(robot, q) for q in Q])
    assert np.allclose(F, one_by_one, rtol=0, atol=1e-9)


def test_one_configuration_and_none():
    robot = get_robot("irb2400")
    frames = JointFrames(robot)
    q = np.zeros(robot.dof)
    assert np.allclose(frames(q)[0], joint_frames_mm(robot, q), atol=1e-9)
    assert frames(np.zeros((0, robot.dof))).shape == (0, robot.dof, 4, 4)
