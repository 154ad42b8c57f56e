"""benchmarks/freeform.py's public parts against benchmarks/parts/freeform/LICENSES.md: each part's file and
SHA-256 are recorded there, each file kept here is the one recorded (its own bytes hashed), and each part fetched
rather than kept (``FETCH``: a copyleft licence) is ignored by git, so a local copy is never committed."""
from __future__ import annotations

import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import freeform as fb  # noqa: E402

LICENSES = (fb.PARTS_DIR / "LICENSES.md").read_text(encoding="utf-8")


PUBLIC = sorted(set(fb.PARTS) - set(fb.GENERATED))   # the generated parts (``GENERATED``) are made, not recorded


def test_generated_parts_are_made_by_a_test():
    assert set(fb.GENERATED) <= set(fb.PARTS)
    for name, where in fb.GENERATED.items():
        assert fb.PARTS[name][2] is None, f"{name} is generated: it has no recorded sum"
        module, func = where.split(":")
        assert f"def {func}(" in (ROOT / "tests" / f"{module}.py").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", PUBLIC)
def test_part_recorded_with_its_sum(name):
    fname, _, sha, _, _ = fb.PARTS[name]
    assert f"{sha}  {fname}" in LICENSES, f"LICENSES.md does not record {fname} with {sha}"


@pytest.mark.parametrize("name", PUBLIC)
def test_kept_file_is_the_recorded_one(name):
    fname, _, sha, _, _ = fb.PARTS[name]
    path = fb.PARTS_DIR / fname
    if name in fb.FETCH and not path.exists():
        pytest.skip(f"{fname} is fetched, not kept ({fb.FETCH[name]})")
    assert hashlib.sha256(path.read_bytes()).hexdigest() == sha


@pytest.mark.parametrize("name", sorted(fb.FETCH))
def test_fetched_part_is_ignored_by_git(name):
    path = fb.PARTS_DIR / fb.PARTS[name][0]
    r = subprocess.run(["git", "-C", str(ROOT), "check-ignore", "-q", "--no-index", str(path)], capture_output=True)
    assert r.returncode == 0, f"{path.relative_to(ROOT)} is not ignored: a local copy could be committed"
    tracked = subprocess.run(["git", "-C", str(ROOT), "ls-files", "--error-unmatch", str(path)], capture_output=True)
    assert tracked.returncode != 0, f"{path.relative_to(ROOT)} is tracked"


def test_contour_runs_are_camtool_s_labels_not_a_guess_from_the_edge(tmp_path):
    # a raster whose last row runs a third of a step from the face's edge, then a contour run: only the run camtool
    # labels contour is one (a guess from the edge dropped such rows on the noether panel: their neighbours
    # measured two step-overs apart)
    seg = np.repeat(np.arange(4), 5)
    contour = seg == 3
    np.savez(tmp_path / "path.npz", segment=seg, contour=contour)
    assert fb.contour_labels(tmp_path / "path.npz", np.array([0, 1, 2, 3])).tolist() == [False, False, False, True]
    assert fb.contour_labels(tmp_path / "path.npz", np.array([1, 3])).tolist() == [False, True]
    np.savez(tmp_path / "rows.npz", segment=seg)          # a raster without a contour run
    assert not fb.contour_labels(tmp_path / "rows.npz", np.array([0, 1, 2, 3])).any()
