"""robocal's calls run BLAS on one thread and give the caller's setting back."""

import pytest
from robots import arm6r
from threadpoolctl import threadpool_info, threadpool_limits

import robocal as rc
from robocal._base.threads import one_blas_thread


def _blas_threads():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


@one_blas_thread
def _inside(depth=0):
    seen = _blas_threads()
    return seen + (_inside(depth - 1) if depth else [])


@one_blas_thread
def _fails():
    raise RuntimeError("inside")


def test_blas_runs_on_one_thread_inside_and_the_callers_setting_comes_back():
    rc.forward_kinematics(arm6r(), [[0.0] * 6])           # scipy's BLAS loaded too
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert set(_inside(depth=2)) == {1}                # nested calls keep the bound
        assert _blas_threads() == before
        with pytest.raises(RuntimeError):
            _fails()
        assert _blas_threads() == before
