"""One-shot ``pdr`` processes run BLAS on one thread unless the user sets a count (pdr.cli.blas_threads)."""

from __future__ import annotations

import os

import pytest

from tests.fresh_process import python_json

_BLAS_THREADS = ("from threadpoolctl import threadpool_info; "
                 "threads = sorted({p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas'}); ")


def _env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    return {**env, **extra}


def test_the_pdr_command_asks_for_one_blas_thread_before_numpy_loads() -> None:
    code = ("import json, os; from pdr.cli import main; rc = main(['inspect', '/no/such/log']); import numpy; "
            + _BLAS_THREADS + "print(json.dumps([rc, os.environ.get('OPENBLAS_NUM_THREADS'), threads]))")
    assert python_json(code, env=_env()) == [2, "1", [1]]


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="OpenBLAS caps its threads at the cores")
def test_a_thread_count_the_user_set_is_kept() -> None:
    code = ("import json; from pdr.cli.blas_threads import single_threaded_blas; applies = single_threaded_blas(); "
            "import numpy; " + _BLAS_THREADS + "print(json.dumps([applies, threads]))")
    assert python_json(code, env=_env(OPENBLAS_NUM_THREADS="2")) == [True, [2]]


def test_it_does_not_apply_once_numpy_is_loaded() -> None:
    code = ("import json, os, numpy; from pdr.cli.blas_threads import single_threaded_blas; "
            "print(json.dumps([single_threaded_blas(), os.environ.get('OPENBLAS_NUM_THREADS')]))")
    assert python_json(code, env=_env()) == [False, None]
