"""camtool.program.remembered: results kept by their inputs' exact values."""
import numpy as np

from camtool.program.remembered import Remembered


def test_a_result_is_computed_once_for_the_same_inputs_and_again_for_others():
    kept, calls = Remembered(keep=3), []

    def norm(x):
        calls.append(1)
        return float(np.linalg.norm(x))

    a = np.array([3.0, 4.0])
    assert kept.value("norm", (a, 1.0), lambda: norm(a)) == 5.0
    assert kept.value("norm", (a.copy(), 1.0), lambda: norm(a)) == 5.0 and len(calls) == 1   # the same values
    b = np.nextafter(a, 10.0)                                                                # one ulp off
    assert kept.value("norm", (b, 1.0), lambda: norm(b)) == norm(b) and len(calls) == 3
    assert kept.value("norm", (a.astype(np.float32), 1.0), lambda: 0.0) == 0.0              # another dtype
    assert kept.value("norm", (a.reshape(2, 1), 1.0), lambda: -1.0) == -1.0                  # another shape
    assert len(kept) == 1   # the fourth result started it again (keep = 3)
    kept.forget()
    assert len(kept) == 0
