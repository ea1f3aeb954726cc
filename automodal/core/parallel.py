"""A parallel ``map`` over threads with one BLAS thread, the worker-count rule, and a map of
independent tasks whose events keep their sequential order (:func:`relayed_map`).

numpy's matrix products and stacked LAPACK calls release the GIL, so threads share the
cores without starting processes. BLAS is held to one thread meanwhile: OpenBLAS's own
threads spin after a product and slowed the next step by 10-25 %. Results never depend on
the number of workers as long as the caller fixes its chunks by the problem's size and
combines them in order (:func:`gather`).
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence, Sized
from contextlib import contextmanager
from typing import Any, TypeVar

T = TypeVar("T")

_LIMITS = threading.Lock()
"""Held while BLAS thread limits are set or restored (:func:`thread_map`)."""

_RUNNING = 0
"""Threads holding a core now: the tasks of :func:`relayed_map` running on its worker
threads (side-by-side sub-bands), less those waiting for tasks of their own. The automatic
worker count inside a task shares the cores the others leave (:func:`free_cores`)."""

_RUNNING_LOCK = threading.Lock()

_THREAD = threading.local()
"""``held``: whether the current thread is counted in :data:`_RUNNING`."""

PARALLEL_MIN_FLOPS = 2e7
"""Below this estimated work the tasks run in the calling thread (a thread pool costs
about 0.1 ms; worker threads pay from a few milliseconds of work)."""


def free_cores() -> int:
    """Cores an automatic worker count may take now: all of them, less one for each thread
    other than the caller that holds one (:data:`_RUNNING`), at least 1.

    Two sub-bands side by side, each with as many workers as cores, ran four threads on two
    cores, and each worker of a replicate or an order scan holds its own working arrays:
    a 38 x 3 dense grid of 6000 lines (family seed 379, f_17) peaked at 1.0 GB. Sharing the
    cores took it to 0.6 GB in the same time; a task left alone gets the cores back at its
    next map.
    """
    cores = os.cpu_count() or 1
    mine = 1 if getattr(_THREAD, "held", False) else 0
    with _RUNNING_LOCK:
        others = _RUNNING - mine
    return max(1, cores - others)


@contextmanager
def _core_held(held: bool) -> Iterator[None]:
    """The calling thread counted in :data:`_RUNNING` (``held``) or not while the context
    lasts: a task holds a core while it runs, and gives it up while it waits for a split of
    its own (a sub-band split again) to run on other threads."""
    global _RUNNING
    before = getattr(_THREAD, "held", False)
    change = int(held) - int(before)
    with _RUNNING_LOCK:
        _RUNNING += change
    _THREAD.held = held
    try:
        yield
    finally:
        with _RUNNING_LOCK:
            _RUNNING -= change
        _THREAD.held = before


def _holding_a_core(task: Callable[..., T]) -> Callable[..., T]:
    """``task`` run holding a core (:func:`_core_held`)."""
    def run(*args: Any) -> T:
        with _core_held(True):
            return task(*args)
    return run


def worker_count(jobs: int | None, n_tasks: int, flops: float = float("inf")) -> int:
    """Worker threads for ``n_tasks`` tasks of ``flops`` floating-point work in all.

    Parameters
    ----------
    jobs : int or None
        Workers asked for (at least 1), or ``None``: the cores free (:func:`free_cores`)
        when the work pays for them (:data:`PARALLEL_MIN_FLOPS`), else 1.
    n_tasks : int
        Tasks to share (never more workers than tasks).
    flops : float
        Estimated work.

    Raises
    ------
    ValueError
        When ``jobs`` is below 1 (``None`` is the only "automatic" value).
    """
    if jobs is None:
        jobs = free_cores() if flops >= PARALLEL_MIN_FLOPS else 1
    elif int(jobs) < 1:
        raise ValueError(f"jobs = {jobs} is not allowed: None (all cores) or an integer >= 1")
    return max(1, min(int(jobs), n_tasks))


_CONTROLLER: list[Any] = [None, -1]
"""threadpoolctl's controller of the loaded native thread pools, and the number of imported
modules when it was made (see :func:`blas_threads`)."""


def _controller() -> Any:
    """A ``threadpoolctl.ThreadpoolController`` of the libraries loaded now, made again only
    after more modules were imported (a new extension module may bring its own BLAS).

    Making one searches every loaded shared library: 1.4-3 ms, which
    ``threadpool_limits`` paid on each of the 20-40 maps of a run; its ``limit`` alone
    takes 20 microseconds. Call with :data:`_LIMITS` held."""
    from threadpoolctl import ThreadpoolController

    if _CONTROLLER[0] is None or _CONTROLLER[1] != len(sys.modules):
        _CONTROLLER[0] = ThreadpoolController()
        _CONTROLLER[1] = len(sys.modules)
    return _CONTROLLER[0]


@contextmanager
def blas_threads(n: int) -> Iterator[None]:
    """At most ``n`` threads in each loaded BLAS (and OpenMP) pool while the context lasts,
    as ``threadpoolctl.threadpool_limits(n)``, the previous limits restored after.

    threadpoolctl's limits are process-wide and not thread-safe: contexts entered from
    several threads at once (sub-bands side by side) set and restore them in turn. The
    limiter is entered and exited as threadpoolctl's context manager: OpenBLAS's shared pool
    obeys one thread at a time (threadpoolctl 3.8), which the exit releases, so a worker
    thread that set a limit does not keep the others' limits from taking effect. (A BLAS
    loaded after the controller was made without an import, through ``ctypes``, is not
    limited.)"""
    with _LIMITS:
        limiter = _controller().limit(limits=n)
        limiter.__enter__()
    try:
        yield
    finally:
        with _LIMITS:
            limiter.__exit__(None, None, None)


@contextmanager
def thread_map(n_jobs: int) -> Iterator[Callable[..., Iterator[Any]]]:
    """A ``map`` over ``n_jobs`` threads (the built-in ``map`` for one), with one BLAS
    thread while the context lasts (:func:`blas_threads`). Results come in the order of
    the inputs."""
    with blas_threads(1):
        if n_jobs == 1:
            yield map
            return
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=n_jobs) as pool:
            yield pool.map


@contextmanager
def freeing_map(
    jobs: int | None, n_tasks: int, flops: float = float("inf")
) -> Iterator[tuple[int, Callable[..., Iterator[Any]]]]:
    """A map for many short calls within one task (a fit's sums, its tests), and its
    workers.

    With ``jobs`` given, or too little work, it is :func:`thread_map` of
    :func:`worker_count` workers. Automatic, the pool has as many workers as cores (at
    most ``n_tasks``), but a call uses it only while another core is free
    (:func:`free_cores`), and runs in the calling thread otherwise: a refinement that began
    beside another sub-band (one core free then) takes the second core as soon as that
    sub-band ends, where a worker count fixed at its start had left it on one core for the
    rest of its run (a 40 x 3 dense grid, seed 413 f_20: 4 s of a 6.7 s refinement on one
    core, the other idle). The caller's results must not depend on the map (chunks fixed
    by the problem, combined in order).

    Yields
    ------
    (int, callable)
        The pool's workers (1 without one) and the map.
    """
    if jobs is not None or flops < PARALLEL_MIN_FLOPS:
        n = worker_count(jobs, n_tasks, flops)
        with thread_map(n) as pmap:
            yield n, pmap
        return
    n = worker_count(os.cpu_count() or 1, n_tasks)  # a worker per core, at most per task
    with thread_map(n) as pmap:
        if n == 1:
            yield n, pmap
            return

        submit = pmap.__self__.submit  # type: ignore[attr-defined]  # pool.map's executor

        def mapped(fn: Callable[..., T], *iterables: Iterable[Any]) -> Iterator[T]:
            if free_cores() > 1:
                return pmap(fn, *iterables)
            return _taking_freed_cores(submit, n - 1, fn, zip(*iterables))

        yield n, mapped


def _taking_freed_cores(
    submit: Callable[..., Any], n_workers: int, fn: Callable[..., T],
    args: Iterable[tuple[Any, ...]],
) -> Iterator[T]:
    """``fn`` over ``args`` in order, in the calling thread, except that whenever a core
    becomes free (:func:`free_cores`, less the items already handed out) the next items are
    handed to the pool's ``submit`` (at most ``n_workers`` at once) while the caller goes on.

    A map that began beside another task, one core free then, takes the second core as
    soon as that task ends: replicates started beside another sub-band (``bench_e2e`` case
    b: the last sub-band's 4 s of replicates on one core while the other was idle). Each
    item is computed alone, so the results are those of the built-in ``map``."""
    items = list(args)
    futures: dict[int, Any] = {}
    ahead = 0  # the next item not yet handed out or run
    for i in range(len(items)):
        ahead = max(ahead, i + 1)
        while ahead < len(items):
            in_flight = sum(not f.done() for f in futures.values())
            if in_flight >= n_workers or free_cores() - 1 - in_flight < 1:
                break
            futures[ahead] = submit(fn, *items[ahead])
            ahead += 1
        future = futures.pop(i, None)
        yield future.result() if future is not None else fn(*items[i])


def gather(
    parts: Iterable[list[T]],
    chunks: Sequence[Sized],
    progress: Callable[[int], None] | None = None,
) -> list[T]:
    """The results of the chunks joined in chunk order, calling ``progress(len(chunk))``
    as each chunk's part arrives."""
    results: list[T] = []
    for chunk, part in zip(chunks, parts):
        results.extend(part)
        if progress:
            progress(len(chunk))
    return results


E = TypeVar("E")


def relayed_map(
    tasks: Sequence[Callable[[Callable[[E], None] | None], T]],
    n_jobs: int,
    report: Callable[[E], None] | None = None,
) -> list[T]:
    """Run independent ``tasks`` on ``n_jobs`` threads, each given its own event callback;
    the events reach ``report`` from the calling thread in the order running the tasks one
    after another would send them.

    Task ``i``'s events are passed on as they come while every task before it has
    finished, and held back until then otherwise. So ``report`` sees the same sequence
    whatever ``n_jobs`` (a progress display is told of one task at a time), and task
    ``i + 1`` can work while task ``i`` does.

    Parameters
    ----------
    tasks : sequence of callables
        ``task(callback)``: its result; ``callback`` is ``None`` when ``report`` is.
    n_jobs : int
        Worker threads (1: the tasks run in turn in the calling thread).
    report : callable, optional
        Receives the events.

    Returns
    -------
    list
        The tasks' results, in order. A task's exception is raised after the events it
        sent; the later tasks' events are not passed on, those not started are cancelled,
        and those running end first.
    """
    if n_jobs <= 1 or len(tasks) <= 1:
        return [task(report) for task in tasks]
    import queue
    from concurrent.futures import ThreadPoolExecutor

    events: queue.SimpleQueue = queue.SimpleQueue()
    ended = object()  # a task's last "event": it has returned or raised

    def sender(i: int) -> Callable[[E], None] | None:
        return None if report is None else (lambda event: events.put((i, event)))

    held: list[list[E]] = [[] for _ in tasks]
    done = [False] * len(tasks)
    with _core_held(False), ThreadPoolExecutor(max_workers=n_jobs) as pool:
        futures = []
        for i, task in enumerate(tasks):
            future = pool.submit(_holding_a_core(task), sender(i))
            # called once the task has ended, so after every event it sent
            future.add_done_callback(lambda _, i=i: events.put((i, ended)))
            futures.append(future)
        current = 0
        while current < len(tasks):
            i, event = events.get()
            if event is ended:
                done[i] = True
            else:
                held[i].append(event)
            while current < len(tasks):
                for event in held[current]:
                    report(event)  # type: ignore[misc]  # events come only with a report
                held[current].clear()
                if not done[current]:
                    break
                error = futures[current].exception()
                if error is not None:  # as in turn: nothing after the failing task
                    for future in futures[current + 1:]:
                        future.cancel()
                    raise error
                current += 1
    return [future.result() for future in futures]
