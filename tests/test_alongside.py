"""Work done alongside (camtool.alongside): a forked child's result, its errors, its cancellation."""
import os
import signal
import time

import numpy as np
import pytest

import functools

from camtool.alongside import Alongside, Standby, cpus_available
from camtool.errors import BadInput

fork_only = pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")


def _big():
    return {"pid": os.getpid(), "values": np.arange(300_000, dtype=float)}  # over a pipe's 64 kB buffer


@fork_only
def test_a_forked_child_hands_its_result_back():
    job = Alongside(_big, forked=True)
    out = job.result()
    assert job.forked and out["pid"] != os.getpid()
    assert np.array_equal(out["values"], np.arange(300_000, dtype=float))


def test_inline_gives_the_same_result_in_this_process():
    job = Alongside(_big, forked=False)
    out = job.result()
    assert out["pid"] == os.getpid() and len(out["values"]) == 300_000


@fork_only
@pytest.mark.parametrize("forked", [True, False])
def test_what_the_function_raised_is_raised_by_result(forked):
    def fails():
        raise BadInput("plots/feed.png: a symlink; camtool does not follow it")
    job = Alongside(fails, forked=forked)
    with pytest.raises(BadInput, match="does not follow it"):
        job.result()


@fork_only
def test_a_child_that_dies_is_reported_not_hung():
    job = Alongside(lambda: os.kill(os.getpid(), signal.SIGKILL), forked=True)
    with pytest.raises(RuntimeError, match="signal 9"):
        job.result()


@fork_only
def test_leaving_the_block_by_an_error_kills_the_child():
    with pytest.raises(ValueError):
        with Alongside(lambda: time.sleep(60), forked=True) as job:
            pid = job._pid
            raise ValueError("the post stage failed")
    with pytest.raises(ProcessLookupError):   # reaped, not left running
        os.kill(pid, 0)


@pytest.mark.parametrize("forked", [True, False])
def test_the_result_and_the_failure_are_kept(forked):
    job = Alongside(lambda: 1, forked=forked)
    assert job.result() == 1 and job.result() == 1 and job.failure() is None

    def fails():
        raise BadInput("the motion check failed")
    job = Alongside(fails, forked=forked)
    first = job.failure()
    assert isinstance(first, BadInput) and job.failure() is first
    with pytest.raises(BadInput):
        job.result()


def test_a_cancelled_job_has_no_result():
    job = Alongside(lambda: 1, forked=False)
    job.cancel()
    with pytest.raises(RuntimeError, match="cancelled"):
        job.result()


def test_default_forks_only_with_a_second_cpu():
    job = Alongside(lambda: 1)
    assert job.result() == 1
    assert job.forked == (hasattr(os, "fork") and cpus_available() > 1)


def _prepared():
    os.environ["CAMTOOL_TEST_STANDBY"] = str(os.getpid())   # what prepare did, seen by fn in the same process


def _where(values):
    return {"prepared_in": os.environ.pop("CAMTOOL_TEST_STANDBY", None), "pid": os.getpid(), "values": values}


def _prepare_fails():
    raise BadInput("open3d is not installed")


@fork_only
def test_a_standby_child_prepares_then_runs_what_it_is_handed():
    values = np.arange(300_000, dtype=float)          # handed over a pipe, over its 64 kB buffer
    with Standby(_prepared, forked=True) as job:
        out = job.start(functools.partial(_where, values)).result()
    assert out["pid"] != os.getpid() and out["prepared_in"] == str(out["pid"])
    assert np.array_equal(out["values"], values) and "CAMTOOL_TEST_STANDBY" not in os.environ


def test_an_unforked_standby_prepares_and_runs_at_result():
    job = Standby(_prepared, forked=False).start(functools.partial(_where, [1, 2]))
    out = job.result()
    assert out == {"prepared_in": str(os.getpid()), "pid": os.getpid(), "values": [1, 2]}


def _made_ahead():
    return {"made_in": os.getpid()}


def _with_ahead(scale, ahead):
    return {"made_in": ahead["made_in"], "pid": os.getpid(), "scale": scale}


@fork_only
@pytest.mark.parametrize("forked", [True, False])
def test_a_standby_hands_what_it_prepared_on_to_its_task(forked):
    """``hand_on``: the task gets ``prepare()``'s value, made in the child ahead (the motion check's part)."""
    with Standby(_made_ahead, forked=forked, hand_on=True) as job:
        out = job.start(functools.partial(_with_ahead, 3)).result()
    assert out["made_in"] == out["pid"] and out["scale"] == 3
    assert (out["pid"] != os.getpid()) == forked


@fork_only
@pytest.mark.parametrize("forked", [True, False])
def test_what_prepare_or_fn_raised_is_raised_by_result(forked):
    job = Standby(_prepare_fails, forked=forked).start(functools.partial(_where, 1))
    with pytest.raises(BadInput, match="not installed"):
        job.result()
    job = Standby(_prepared, forked=forked).start(functools.partial(_prepare_fails))
    assert isinstance(job.failure(), BadInput)


@fork_only
def test_a_standby_never_started_is_killed_on_leaving_the_block():
    with Standby(_prepared, forked=True) as job:
        pid = job._pid
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)
    with pytest.raises(RuntimeError, match="cancelled"):
        job.result()


def test_a_standby_is_started_once_and_has_no_result_before():
    job = Standby(_prepared, forked=False)
    with pytest.raises(RuntimeError, match="not started"):
        job.result()
    job.start(functools.partial(_where, 1))
    with pytest.raises(RuntimeError, match="started already"):
        job.start(functools.partial(_where, 2))


def _first(prepared):
    return {"made_in": os.getpid(), "prepared": prepared, "values": np.arange(300_000, dtype=float)}


def _second(values, before):
    return {**before, "second": float(np.sum(values)), "second_in": os.getpid()}


def _slow(before):
    time.sleep(0.5)
    return before


@fork_only
@pytest.mark.parametrize("forked", [True, False])
def test_a_standby_runs_its_tasks_in_order_each_given_the_one_before(forked):
    """``then``: a further task, given the previous task's value with ``hand_on`` (the map's sweep of the
    raster, drawn once the plan is known); ``result()`` is the last task's."""
    values = np.arange(300_000, dtype=float)
    with Standby(lambda: "ready", forked=forked, hand_on=True) as job:
        out = job.start(_first).then(functools.partial(_second, values)).result()
    assert out["prepared"] == "ready" and out["made_in"] == out["second_in"]
    assert out["second"] == float(values.sum()) and (out["made_in"] != os.getpid()) == forked


@fork_only
def test_a_task_handed_while_the_child_works_does_not_wait_for_it():
    """Handing a task larger than a pipe's buffer returns at once while the child still works on the one
    before: a thread of the child reads it as it comes."""
    values = np.arange(1_000_000, dtype=float)   # 8 MB
    with Standby(dict, forked=True, hand_on=True) as job:
        job.start(_slow)
        t0 = time.perf_counter()
        job.then(functools.partial(_second, values))
        handed_s = time.perf_counter() - t0
        out = job.result()
    assert handed_s < 0.4 and out["second"] == float(values.sum())


@fork_only
@pytest.mark.parametrize("forked", [True, False])
def test_after_a_task_raised_the_later_ones_do_not_run(forked):
    job = Standby(dict, forked=forked, hand_on=True)
    job.start(_fails_with).then(functools.partial(_second, np.ones(3)))
    with pytest.raises(BadInput, match="not installed"):
        job.result()


def _fails_with(_before):
    _prepare_fails()


def test_then_needs_a_start():
    with pytest.raises(RuntimeError, match="not started"):
        Standby(lambda: None, forked=False).then(functools.partial(_where, 1))


@fork_only
def test_a_standby_forked_later_does_not_keep_an_earlier_one_waiting():
    """A child forked after a standby holds a copy of that standby's task pipe; the standby's child is told
    that no more tasks come, so it does not wait for the pipe's end (the raster task forks three)."""
    def timed_out(*_):
        raise TimeoutError("the standby's child waited for more tasks")
    old = signal.signal(signal.SIGALRM, timed_out)
    signal.alarm(20)
    try:
        with Standby(dict, forked=True, hand_on=True) as first, Standby(dict, forked=True) as second:
            first.start(_slow)
            assert first.result() == {}
            second.cancel()
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def test_a_child_dies_with_a_parent_that_ends_early():
    """A parent that ends without waiting (an error, a signal) takes its child along (PR_SET_PDEATHSIG): no
    helper computes on after camtool has exited."""
    import subprocess
    import sys
    import time

    code = ("import os, sys, time\n"
            "from camtool.alongside import Alongside\n"
            "child = Alongside(lambda: time.sleep(60), forked=True)\n"
            "print(child._pid, flush=True)\n"
            "os._exit(3)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 3, out.stderr
    pid = int(out.stdout.split()[0])
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return          # killed, not yet reaped by whoever adopted it
        except FileNotFoundError:
            return
        time.sleep(0.1)
    os.kill(pid, 9)
    raise AssertionError("the child outlived its parent")
