"""The GIL is released during long calls: a second Python thread makes progress while the main
thread is inside a jaws query or a pipeline run.

A busy Python thread counts its loop iterations into 1 ms bins of the wall clock. The main thread
notes the wall clock just before and just after one long call; the bins strictly inside that
window, away from its edges (where the interpreter may hand the GIL over around the call), must
hold many iterations. Had the call kept the GIL, the counting thread could not have run at all
inside the window. The switch interval is shortened so that the hand-overs at the edges take
well under the margin."""

from __future__ import annotations

import sys
import threading
import time
from typing import Callable

import numpy as np

import haptic

IDENTITY = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
BIN_S = 1e-3
MARGIN_S = 5e-3  # 50 switch intervals of 0.1 ms
MIN_ITERATIONS = 50


class Counter(threading.Thread):
    """Counts loop iterations per millisecond of `time.perf_counter()` since `origin`."""

    def __init__(self, seconds: float) -> None:
        super().__init__(daemon=True)
        self.bins = [0] * int(seconds / BIN_S + 1)
        self.origin = time.perf_counter()
        self.stop = threading.Event()
        self.started = threading.Event()

    def run(self) -> None:
        bins, origin, n = self.bins, self.origin, len(self.bins)
        clock, stop = time.perf_counter, self.stop
        self.started.set()
        while not stop.is_set():
            i = int((clock() - origin) / BIN_S)
            if i >= n:
                break
            bins[i] += 1

    def between(self, t0: float, t1: float) -> int:
        lo = int((t0 - self.origin) / BIN_S) + 1
        hi = int((t1 - self.origin) / BIN_S)
        return sum(self.bins[max(lo, 0):max(hi, 0)])


def progress_during(call: Callable[[], object], budget_s: float) -> tuple[int, float, object]:
    """Runs `call` in this thread while a Counter runs; returns the counter's iterations inside
    the call (its edges excluded), the call's duration and its result."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    counter = Counter(budget_s)
    try:
        counter.start()
        assert counter.started.wait(5.0)
        time.sleep(0.01)  # let it run a little first
        t0 = time.perf_counter()
        result = call()
        t1 = time.perf_counter()
    finally:
        counter.stop.set()
        counter.join(5.0)
        sys.setswitchinterval(old)
    assert t1 - counter.origin < budget_s, "the call outlasted the counter's budget"
    return counter.between(t0 + MARGIN_S, t1 - MARGIN_S), t1 - t0, result


def test_the_measure_tells_a_held_gil_from_a_released_one():
    """The measure itself: `sum` over a long range runs in C holding the GIL (no bytecode, so
    no switch), and the counter gets nothing inside it; `time.sleep` releases the GIL, and the
    counter runs all along."""
    count, duration, total = progress_during(lambda: sum(range(30_000_000)), 60.0)
    assert total == 30_000_000 * (30_000_000 - 1) // 2
    assert duration > 4 * MARGIN_S
    assert count <= 5, f"{count} iterations while the GIL was held: the measure is broken"

    count, duration, _ = progress_during(lambda: time.sleep(0.1), 10.0)
    assert duration >= 0.1
    assert count > 10 * MIN_ITERATIONS


def test_gil_released_during_a_jaws_query(jaws_lod):
    # The exact query (threshold 0) on the jaws in occlusion: about 20 ms here, repeated for at
    # least ten margins so that a faster machine still gives a span to measure in.
    jaws_lod.query(IDENTITY, delta=1e-3, threshold=0.0)  # warm caches

    def queries():
        start = time.perf_counter()
        while True:
            result = jaws_lod.query(IDENTITY, delta=1e-3, threshold=0.0)
            if time.perf_counter() - start > 10 * MARGIN_S:
                return result

    count, duration, (contacts, stats) = progress_during(queries, 60.0)
    assert len(contacts) > 0
    assert duration > 4 * MARGIN_S, f"the query took {duration * 1e3:.1f} ms: too short to tell"
    assert count > MIN_ITERATIONS, (
        f"the other thread ran {count} loop iterations during a {duration * 1e3:.0f} ms query"
    )


def test_gil_released_during_run_virtual(spoon_cup):
    count, duration, run = progress_during(lambda: haptic.run_virtual(spoon_cup, 2.0), 120.0)
    assert len(run.t) == 2000
    assert duration > 4 * MARGIN_S, f"the run took {duration * 1e3:.1f} ms: too short to tell"
    assert count > MIN_ITERATIONS, (
        f"the other thread ran {count} loop iterations during a {duration * 1e3:.0f} ms run"
    )


def test_gil_released_while_clustering_a_large_set():
    rng = np.random.default_rng(11)
    k = 800_000  # uniform in a box: Lloyd's method needs many iterations
    p = rng.uniform(-0.05, 0.05, size=(k, 3))
    n = np.tile([0.0, 0.0, -1.0], (k, 1))
    depth = rng.uniform(-5e-4, 5e-4, size=k)
    contacts = haptic.Contacts(p, p, p - depth[:, None] * n, n, depth)
    clusterer = haptic.Clusterer(max_clusters=5, max_iterations=100, warm_start=False)
    count, duration, reps = progress_during(lambda: clusterer.cluster(contacts, 1e-3), 60.0)
    assert len(reps) == 10  # five clusters, each a torque pair
    assert duration > 4 * MARGIN_S, (
        f"clustering {k} contacts took {duration * 1e3:.1f} ms: too short to tell"
    )
    assert count > MIN_ITERATIONS, (
        f"the other thread ran {count} loop iterations during {duration * 1e3:.0f} ms of "
        "clustering"
    )
