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
