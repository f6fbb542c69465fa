"""Worker processes for the evaluations that share their work (``stress --workers``, ``shift --workers``).

The workers are forked from a server process (multiprocessing's ``forkserver``) that has imported the simulator,
torch and the policies' code once: a pool of N workers starts one fresh interpreter, not N, and a second pool in
the same process starts none. The server is a fresh interpreter, not a copy of the caller: no thread of the
caller's (torch's, a progress bar's) is forked. Each worker uses one math thread, so ``--workers N`` uses N cores.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

PRELOAD = ["autoscoop.evaluation.stress", "autoscoop.evaluation.shift"]
"""Imported once by the server; the jobs the pools run live in these modules."""


def one_thread_per_worker() -> None:
    """Worker set-up: one math thread each (torch, BLAS), so ``--workers N`` uses N cores, not N x all."""
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ.setdefault(name, "1")


def worker_pool(workers: int) -> ProcessPoolExecutor:
    """A pool of ``workers`` processes, forked from the server (started on first use, with this process's
    environment at that time: the machine it simulates included)."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    return ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=one_thread_per_worker)
