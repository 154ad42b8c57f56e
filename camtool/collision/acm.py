"""The allowed-collision matrix of a robot, made the way MoveIt's setup assistant makes one.

A pair of robot bodies is allowed (never measured) when it is

- ``adjacent``: consecutive bodies of the chain (bodies on joint frames
  without a body of their own in between count as consecutive), or the rail
  and the carriage;
- ``always``: in collision in every one of the random samples;
- ``never``: in collision in none of them (MoveIt's "never in collision",
  10 000 samples by default there; here ``ACM_SAMPLES``).

Samples are uniform within the joint limits from a fixed seed, so the matrix
is deterministic. The tool is not in the matrix: it is measured against every
link except the one it is mounted on, whatever the tool. Built-in robots ship
their matrix as data (``camtool/collision/data/acm_<robot>.json``, written by
``python scripts/rebuild_acms.py``); it is used when the bodies it was made
for (a hash of their shapes) are the robot's bodies, and made again otherwise.
A job overrides it with ``cell.allow_collision`` and ``cell.check_collision``.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BadInput
from ..robots.joint_frames import joint_frames_mm

ACM_SAMPLES = 5000
ACM_SEED = 0
DATA_DIR = Path(__file__).resolve().parent / "data"


@dataclass(frozen=True)
class AllowedCollisions:
    """Allowed body pairs with the reason (adjacent, always, never, job)."""

    reasons: dict = field(default_factory=dict)   # frozenset({a, b}) -> reason
    samples: int = 0
    geometry_hash: str = ""

    def allowed(self, a: str, b: str) -> bool:
        return frozenset((a, b)) in self.reasons

    def overridden(self, allow=(), check=(), names=()) -> "AllowedCollisions":
        known = set(names)
        reasons = dict(self.reasons)
        for what, pairs in (("cell.allow_collision", allow), ("cell.check_collision", check)):
            for a, b in pairs:
                for x in (a, b):
                    if x not in known:
                        raise BadInput(f"{what}: {x!r} is not a body of the robot (bodies: {', '.join(sorted(known))})")
                if what == "cell.allow_collision":
                    reasons[frozenset((a, b))] = "job"
                else:
                    reasons.pop(frozenset((a, b)), None)
        return AllowedCollisions(reasons, self.samples, self.geometry_hash)

    def describe(self) -> dict:
        rows = sorted([sorted(p) + [r] for p, r in self.reasons.items()])
        return {"samples": self.samples, "pairs": [{"a": a, "b": b, "reason": r} for a, b, r in rows]}


def geometry_hash(robot, bodies) -> str:
    """Hash of the robot's link bodies and joint limits (what the matrix depends on)."""
    text = json.dumps({"bodies": [b.describe() for b in bodies if b.kind != "tool"],
                       "lower": np.round(robot.limits.lower, 9).tolist(),
                       "upper": np.round(robot.limits.upper, 9).tolist(), "samples": ACM_SAMPLES,
                       "seed": ACM_SEED}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _adjacent(bodies) -> set:
    moving = sorted([b for b in bodies if b.kind != "tool"], key=lambda b: b.parent)
    out = set()
    for x, y in zip(moving[:-1], moving[1:]):
        out.add(frozenset((x.name, y.name)))
    for x in moving:
        for y in moving:
            if x is not y and x.parent == y.parent:
                out.add(frozenset((x.name, y.name)))
    return out


def compute_acm(robot, bodies, samples: int = ACM_SAMPLES, seed: int = ACM_SEED) -> AllowedCollisions:
    """Make the matrix of a robot's link bodies by sampling (module docstring)."""
    import coal

    links = [b for b in bodies if b.kind != "tool"]
    reasons = {p: "adjacent" for p in _adjacent(links)}
    cand = [(i, j) for i in range(len(links)) for j in range(i + 1, len(links))
            if frozenset((links[i].name, links[j].name)) not in reasons
            and not (links[i].parent <= 0 and links[j].parent <= 0)]
    if cand:
        rng = np.random.default_rng(seed)
        lo, hi = robot.limits.lower, robot.limits.upper
        Q = lo + rng.random((samples, robot.dof)) * (hi - lo)
        geo = [b.coal_geometry() for b in links]
        hits = np.zeros(len(cand), np.int64)
        data = robot.model.createData()
        req, res = coal.CollisionRequest(), coal.CollisionResult()
        for q in Q:
            F = joint_frames_mm(robot, q, data)
            tf = []
            for b in links:
                T = (b.local_T_mm if b.parent <= 0 else F[b.parent - 1] @ b.local_T_mm)
                tf.append(coal.Transform3s(T[:3, :3].copy(), T[:3, 3].copy()))
            for k, (i, j) in enumerate(cand):
                res.clear()
                hits[k] += coal.collide(geo[i], tf[i], geo[j], tf[j], req, res) > 0
        for k, (i, j) in enumerate(cand):
            if hits[k] == 0:
                reasons[frozenset((links[i].name, links[j].name))] = "never"
            elif hits[k] == samples:
                reasons[frozenset((links[i].name, links[j].name))] = "always"
    return AllowedCollisions(reasons, samples, geometry_hash(robot, bodies))


def _to_json(acm: AllowedCollisions, robot_name: str) -> str:
    d = acm.describe()
    d.update(robot=robot_name, geometry_hash=acm.geometry_hash)
    return json.dumps(d, indent=1, sort_keys=True) + "\n"


def _from_json(text: str) -> AllowedCollisions:
    d = json.loads(text)
    return AllowedCollisions({frozenset((p["a"], p["b"])): p["reason"] for p in d["pairs"]}, int(d["samples"]),
                             d["geometry_hash"])


_MEMO: dict = {}


def robot_acm(robot, bodies) -> AllowedCollisions:
    """The shipped matrix when it was made for these bodies, else one made now (and kept for the process)."""
    h = geometry_hash(robot, bodies)
    if h in _MEMO:
        return _MEMO[h]
    from .. import safe_io

    acm = None
    if safe_io.safe_name(robot.name) == robot.name:  # a robot's name never reaches outside the shipped data
        f = DATA_DIR / f"acm_{robot.name}.json"
        try:  # the shipped matrix, read once through safe_io; anything else is made now
            cached = _from_json(safe_io.read_input_bytes(f, "manifest", follow=False).decode())
        except (BadInput, ValueError, KeyError, TypeError, RecursionError):
            cached = None
        if cached is not None and cached.geometry_hash == h:
            acm = cached
    if acm is None:
        acm = compute_acm(robot, bodies)
    _MEMO[h] = acm
    return acm


def write_shipped_acms() -> dict[str, int]:
    """Write the shipped matrices of the built-in robots (camtool/collision/data/acm_<robot>.json);
    returns the number of allowed pairs per robot (``scripts/rebuild_acms.py`` prints them)."""
    from ..robots import BUILTIN_ROBOTS, get_robot
    from .shapes import robot_bodies

    counts = {}
    for name in BUILTIN_ROBOTS:
        robot = get_robot(name)
        acm = compute_acm(robot, robot_bodies(robot, 25.0))
        (DATA_DIR / f"acm_{name}.json").write_text(_to_json(acm, name))
        counts[name] = len(acm.reasons)
    return counts
