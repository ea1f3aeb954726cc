"""The parallel map: one result whatever the number of workers."""

from __future__ import annotations

import numpy as np
import pytest

from automodal.core import bilinear, bootstrap, parallel, replicates, subspace
from automodal.core import simulate as sim
from automodal.core.parallel import (
    PARALLEL_MIN_FLOPS,
    blas_threads,
    free_cores,
    freeing_map,
    gather,
    relayed_map,
    thread_map,
    worker_count,
)


def test_worker_count_rule(monkeypatch):
    monkeypatch.setattr("os.cpu_count", lambda: 8)
    assert worker_count(None, 100, PARALLEL_MIN_FLOPS) == 8
    assert worker_count(None, 100, PARALLEL_MIN_FLOPS / 2) == 1  # too little work
    assert worker_count(None, 3) == 3  # never more workers than tasks
    assert worker_count(2, 100, 0.0) == 2  # asked for: used whatever the work
    assert worker_count(16, 5) == 5
    for bad in (0, -1):
        with pytest.raises(ValueError, match="None .* or an integer >= 1"):
            worker_count(bad, 10)


def _counting_together(parties: int):
    """A task that, once ``parties`` threads have reached it, returns the automatic worker
    count it sees while all of them are still running."""
    import threading

    together = threading.Barrier(parties)

    def task(_):
        together.wait(timeout=10)
        n = worker_count(None, 100)
        together.wait(timeout=10)
        return n

    return task


def test_tasks_side_by_side_share_the_cores(monkeypatch):
    """Inside two tasks of relayed_map running at once, the automatic worker count leaves
    a core to the other task; a task running alone, and the caller, get them all."""
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    task = _counting_together(2)
    assert relayed_map([task, task], 2) == [3, 3]
    assert relayed_map([lambda _: worker_count(None, 100)], 2) == [4]
    assert worker_count(None, 100) == 4


def test_a_task_waiting_for_its_own_split_gives_up_its_core(monkeypatch):
    """A task that runs a map of its own (a sub-band split again) holds no core while it
    waits: with one other task running, each of its two inner tasks may take 2 of 4 cores."""
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    task = _counting_together(3)
    assert relayed_map([lambda _: relayed_map([task, task], 2), task], 2) == [[2, 2], 2]
    assert worker_count(None, 100) == 4


def _beside_a_sibling(monkeypatch, task):
    """``task(end_sibling)`` run on two cores beside a sibling task that holds one of them
    until ``end_sibling()``, which returns once the sibling's core is free; returns
    ``task``'s result and its thread."""
    import threading
    import time

    monkeypatch.setattr("os.cpu_count", lambda: 2)
    started, release = threading.Event(), threading.Event()

    def sibling(_):
        started.set()
        release.wait(10)

    def end_sibling():
        release.set()
        for _ in range(2000):
            if free_cores() > 1:
                return
            time.sleep(0.005)

    def run(_):
        started.wait(10)
        return task(end_sibling), threading.get_ident()

    return relayed_map([sibling, run], 2)[1]


def _whose(k):
    import threading
    import time

    time.sleep(0.05)
    return threading.get_ident()


def test_a_freeing_map_takes_a_core_as_soon_as_it_is_free(monkeypatch):
    """Begun beside another task (one core free), an automatic freeing map runs its calls
    in the calling thread; once that task has ended, on two workers. Workers asked for are
    the pool's."""

    def refining(end_sibling):
        with freeing_map(None, 2) as (n, pmap):
            before = set(pmap(_whose, range(2)))
            end_sibling()
            after = set(pmap(_whose, range(2)))
        with freeing_map(2, 2) as (asked, amap):
            fixed = set(amap(_whose, range(2)))
        return n, before, after, asked, fixed

    (n, before, after, asked, fixed), me = _beside_a_sibling(monkeypatch, refining)
    assert n == 2 and before == {me}
    assert me not in after and len(after) == 2
    assert asked == 2 and me not in fixed


def test_a_freeing_map_hands_items_to_a_core_freed_while_it_runs(monkeypatch):
    """One call begun beside another task runs its first items in the calling thread; once
    the task ends, the next items go to the pool while the caller works on. The results
    keep their order."""

    def mapping(end_sibling):
        def item(k):
            if k == 1:  # the sibling ends during the second item
                end_sibling()
            return k, _whose(k)

        with freeing_map(None, 8) as (_, pmap):
            return list(pmap(item, range(8)))

    out, me = _beside_a_sibling(monkeypatch, mapping)
    assert [k for k, _ in out] == list(range(8))
    threads = [t for _, t in out]
    assert threads[:2] == [me, me]
    assert any(t != me for t in threads[2:])


@pytest.mark.parametrize("n_jobs", [1, 2, 3])
def test_thread_map_keeps_input_order(n_jobs):
    with thread_map(n_jobs) as pmap:
        out = list(pmap(lambda x: x * x, range(20)))
    assert out == [x * x for x in range(20)]


def _blas_threads_now() -> list[int]:
    from threadpoolctl import threadpool_info

    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


def test_blas_threads_limits_every_blas_and_restores_it_and_reuses_its_controller():
    import scipy.linalg  # noqa: F401  (its own BLAS, loaded before the controller is made)

    with thread_map(2) as pmap:  # the thread pool's modules imported before the controller
        list(pmap(abs, range(2)))
    before = _blas_threads_now()
    assert before
    with blas_threads(1):
        assert _blas_threads_now() == [1] * len(before)
        first = parallel._controller()
        with thread_map(2) as pmap:  # nested, as a map inside the pipeline's limit
            assert list(pmap(lambda _: _blas_threads_now(), range(2))) == [[1] * len(before)] * 2
        assert parallel._controller() is first  # no import since: the same controller
    assert _blas_threads_now() == before


def test_a_limit_set_on_a_worker_thread_does_not_keep_the_others_from_limiting():
    """OpenBLAS's shared pool obeys one controlling thread (threadpoolctl 3.8): a worker
    that set and restored a limit, and lives on, must have let go of it."""
    from concurrent.futures import ThreadPoolExecutor

    import scipy.linalg  # noqa: F401

    def limited_once() -> None:
        with blas_threads(1):
            pass

    before = _blas_threads_now()
    with ThreadPoolExecutor(1) as pool:
        pool.submit(limited_once).result()  # the worker stays alive until the pool closes
        with blas_threads(1):
            assert _blas_threads_now() == [1] * len(before)
    assert _blas_threads_now() == before


def test_gather_joins_in_chunk_order_and_reports_progress():
    chunks = [range(0, 3), range(3, 5), range(5, 9)]
    seen: list[int] = []
    out = gather(([i for i in r] for r in chunks), chunks, seen.append)
    assert out == list(range(9))
    assert seen == [3, 2, 4]


def test_thread_map_gives_the_same_floating_point_result_for_1_and_2_workers():
    rng = np.random.default_rng(0)
    mats = [rng.standard_normal((60, 60)) for _ in range(8)]

    def work(a):
        return np.linalg.eigvalsh(a @ a.T)

    with thread_map(1) as pmap:
        one = list(pmap(work, mats))
    with thread_map(2) as pmap:
        two = list(pmap(work, mats))
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)


def test_replicates_are_identical_for_1_and_2_workers():
    system = sim.damp(sim.chain(4), "rayleigh", zeta=0.02)
    freq = sim.frequency_lines(1.25 * sim.natural_frequencies_hz(system).max(), 300)
    data, _ = sim.simulate_test(system, [0, 2, 3], [3], freq, "displacement", noise=0.02, seed=1)
    keep = data.frequency > 0
    w = 2 * np.pi * data.frequency[keep]
    T = bilinear.default_scale(w[0], w[-1])
    z = bilinear.to_unit_circle(w, T)
    H = data.frf[keep] / subspace.channel_scales(data.frf[keep])[None, :, None]
    basis = subspace.row_basis(z, subspace.block_rows(16, 3))
    weights = bootstrap.line_weights(H.shape[0], 12, np.random.default_rng(3))
    seen: list[int] = []
    one = replicates.run_replicates(basis, H, 16, T, weights, 1)
    two = replicates.run_replicates(basis, H, 16, T, weights, 2, progress=seen.append)
    assert sum(seen) == 12 and len(one) == len(two) == 12
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a.poles, b.poles)
        np.testing.assert_array_equal(a.shapes, b.shapes)
        assert a.path == b.path


@pytest.mark.parametrize("n_jobs", [1, 2, 4])
def test_relayed_map_passes_events_in_sequential_order_from_the_calling_thread(n_jobs):
    """Tasks that end in the reverse of their order still have their events relayed task
    by task, from the caller's thread; results come in task order."""
    import threading
    import time

    caller = threading.get_ident()
    seen: list[tuple[int, int, bool]] = []

    def task(i: int):
        def run(send):
            for step in range(3):
                time.sleep(0.002 * (4 - i))  # the later tasks finish first
                if send is not None:
                    send((i, step))
            return i * 10
        return run

    out = relayed_map([task(i) for i in range(4)], n_jobs,
                      lambda e: seen.append((*e, threading.get_ident() == caller)))
    assert out == [0, 10, 20, 30]
    assert seen == [(i, step, True) for i in range(4) for step in range(3)]
    assert relayed_map([task(i) for i in range(2)], n_jobs) == [0, 10]  # no report


@pytest.mark.parametrize("n_jobs", [1, 3])
def test_relayed_map_raises_a_task_error_after_its_events_and_relays_nothing_later(n_jobs):
    def bad(send):
        send("before")
        raise RuntimeError("task failed")

    seen: list[str] = []
    with pytest.raises(RuntimeError, match="task failed"):
        relayed_map([lambda send: send("first"), bad, lambda send: send("later")], n_jobs,
                    seen.append)
    assert seen == ["first", "before"]
