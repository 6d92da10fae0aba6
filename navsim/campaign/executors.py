"""Campaign executors: local processes (a fork server, one BLAS thread per worker, workers that
die with the campaign) or a Dask ``distributed`` cluster (one future per episode, lost results
resubmitted), and :func:`run_campaign`, which runs what is missing. See :mod:`navsim.campaign`.
"""


from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Protocol, Sequence, cast

from ..errors import ConfigError, DependencyNotInstalled
from .database import finished_keys, open_database, store
from .spec import CampaignInterrupted, CampaignSpec
from .tasks import EpisodeTask, episode_tasks, run_episode_task

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS",
                "NUMEXPR_NUM_THREADS")


class DaskClient(Protocol):
    """What the campaign uses of a ``distributed.Client`` (a running client may be passed
    as ``scheduler``): ``submit(fn, *args, pure=False)`` returning a future, and ``close()``."""

    def submit(self, func: Callable[..., Any], *args: Any, **kwargs: Any) -> Any: ...

    def close(self) -> Any: ...


@contextlib.contextmanager
def _single_threaded_children() -> Iterator[None]:
    """Environment for worker processes started inside: one BLAS / OpenMP thread each
    (variables the user set are kept). The episodes use small matrices, where BLAS
    threads only cost wake-ups (measured: 0.43 s CPU for six 20-s episodes with the
    default threads, 0.36 s with one), and several processes with several threads
    each oversubscribe the cores. Dask's nanny does the same for its workers."""
    added = [k for k in _THREAD_VARS if k not in os.environ]
    for k in added:
        os.environ[k] = "1"
    try:
        yield
    finally:
        for k in added:
            os.environ.pop(k, None)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _die_with_parent(campaign_pid: int) -> None:
    """Worker initializer: the worker is killed when the campaign process dies, even by
    SIGKILL. Its parent is the campaign process (``spawn``) or the fork server
    (``forkserver``), which exits when the campaign process dies. Linux:
    ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` for the death of the parent; everywhere a watcher
    thread checks once a second that the parent is the same and the campaign process
    alive, and exits the worker otherwise."""
    import signal
    import sys
    import threading

    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG = 1
        except (OSError, AttributeError):
            pass
    if not _alive(campaign_pid) or (parent == 1 and campaign_pid != 1):  # died before the prctl took effect
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(1.0)
            if os.getppid() != parent or not _alive(campaign_pid):
                os._exit(1)

    threading.Thread(target=watch, name="navsim-parent-watch", daemon=True).start()


# imported once by the fork server, so that forked workers start with the episode code loaded
_FORKSERVER_PRELOAD = ["navsim.campaign", "navsim.report", "navsim.episode", "navsim.estimators", "navsim.metrics",
                       "navsim.campaign.warm"]


def _worker_context() -> Any:
    """The start method of local workers: ``forkserver`` (preloading the episode code)
    where available, else ``spawn``."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_FORKSERVER_PRELOAD)
        return ctx
    return multiprocessing.get_context("spawn")


def _run_local(todo: list[EpisodeTask], workers: int, handle: Callable[[EpisodeTask, dict], None]) -> None:
    if workers == 0:
        for task in todo:
            handle(task, run_episode_task(task))
        return
    # forkserver (or spawn): no fork of this process, which may run threads; the fork
    # server and the workers start during the submissions below with the environment set there
    pool = cf.ProcessPoolExecutor(max_workers=workers, mp_context=_worker_context(),
                                  initializer=_die_with_parent, initargs=(os.getpid(),))
    try:
        with _single_threaded_children():
            futures = {pool.submit(run_episode_task, t): t for t in todo}
        for fut in cf.as_completed(futures):
            try:
                out = fut.result()
            except cf.process.BrokenProcessPool as exc:
                raise CampaignInterrupted(f"a local worker process died ({exc}); the finished episodes are in the "
                                          "database, run the campaign again to finish the rest") from None
            handle(futures[fut], out)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


DASK_RESUBMITS = 3  # times a lost episode result is resubmitted before it is stored as failed


def _run_dask(todo: list[EpisodeTask], scheduler: str | DaskClient, handle: Callable[[EpisodeTask, dict], None],
              timeout_s: float = 30.0) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise DependencyNotInstalled("distributed", "campaign") from None
    own = isinstance(scheduler, str)
    client: DaskClient
    if own:
        try:
            client = Client(scheduler, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as exc:
            raise CampaignInterrupted(f"no Dask scheduler answered at {scheduler} within {timeout_s:g} s "
                                      f"({type(exc).__name__}: {exc})") from None
    else:
        client = cast(DaskClient, scheduler)
    try:
        futures = {}
        for task in todo:
            fut = client.submit(run_episode_task, task, pure=False)
            futures[fut.key] = (fut, task, 0)
        pending = as_completed([f for f, _, _ in futures.values()])
        for fut in pending:
            task, tries = futures.pop(fut.key)[1:]
            error = None
            if fut.status == "error":  # e.g. KilledWorker: the task killed its workers too often
                error = fut.exception()
            else:
                try:
                    out = fut.result()
                except Exception as exc:  # noqa: BLE001 - the result was lost with its worker
                    # (cancelled, or the scheduler lost it between completion and fetch):
                    # run the episode again elsewhere, a bounded number of times
                    fut.release()
                    if tries < DASK_RESUBMITS:
                        again = client.submit(run_episode_task, task, pure=False)
                        futures[again.key] = (again, task, tries + 1)
                        pending.add(again)
                        continue
                    error = exc
            if error is not None:
                out = {"status": "failed", "scores": None, "outages": None, "samples": None,
                       "error": f"{type(error).__name__}: {error}", "wall_s": None, "cpu_s": None, "worker": None}
            fut.release()
            handle(task, out)
    finally:
        for fut, *_ in futures.values():
            fut.cancel()
        if own:
            client.close()


@dataclass
class CampaignResult:
    """What one call of :func:`run_campaign` did: ``total`` episodes of the campaign,
    ``skipped`` already in the database, ``ran`` now, ``failed`` of those."""

    total: int
    skipped: int
    ran: int = 0
    failed: int = 0
    wall_s: float = 0.0


def run_campaign(spec: CampaignSpec, *, scheduler: str | DaskClient | None = None, workers: int | None = None,
                 retry_failed: bool = False,
                 progress: bool = True, on_result: Callable[[EpisodeTask, dict], None] | None = None,
                 tasks: Sequence[EpisodeTask] | None = None) -> CampaignResult:
    """Run the episodes of the campaign not yet in its database.

    Parameters
    ----------
    spec : the campaign. scheduler : None for local processes, a ``tcp://HOST:PORT``
        address or a ``distributed.Client`` for Dask.
    workers : local processes (default: every core, ``os.cpu_count()``); 0 runs the
        episodes in this process.
    retry_failed : run again the episodes recorded as failed.
    progress : tqdm bar on stderr (episodes done, failures, time left).
    on_result : called with (task, outcome) after each row is committed (a test hook;
        an exception raised there stops the campaign, the rows so far are kept).
    tasks : run only these (a subset of :func:`episode_tasks`); default all.
    """
    from tqdm import tqdm

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 0):
        raise ConfigError("--workers", "a non-negative integer", workers)
    all_tasks = list(tasks) if tasks is not None else episode_tasks(spec)
    con = open_database(spec.database, spec.divergence_threshold_m)
    t0 = time.perf_counter()
    try:
        done = finished_keys(con, include_failed=not retry_failed)
        todo = [t for t in all_tasks if t.key not in done]
        result = CampaignResult(total=len(all_tasks), skipped=len(all_tasks) - len(todo))
        bar = tqdm(total=len(todo), unit="episode", desc=spec.name, file=sys.stderr, disable=not progress,
                   leave=False, dynamic_ncols=True)
        bar.set_postfix(failed=0, skipped=result.skipped)

        def handle(task: EpisodeTask, out: dict) -> None:
            store(con, task, out)
            result.ran += 1
            result.failed += out["status"] != "ok"
            bar.set_postfix(failed=result.failed, skipped=result.skipped, refresh=False)
            bar.update(1)
            if on_result is not None:
                on_result(task, out)

        try:
            if not todo:
                pass
            elif scheduler is not None:
                _run_dask(todo, scheduler, handle)
            else:
                _run_local(todo, (os.cpu_count() or 1) if workers is None else workers, handle)
        finally:
            bar.refresh()  # the final count and failures, whatever the refresh interval
            bar.close()
    finally:
        con.close()
    result.wall_s = time.perf_counter() - t0
    return result
