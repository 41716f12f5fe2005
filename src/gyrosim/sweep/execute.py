"""Run a sweep's chunks in this process or as tasks on a ``dask.distributed`` cluster, writing each as it arrives.

In the process (the default), the chunks run one after another, each one compiled call of the engine over its
samples (OpenMP spreads the bodies over every core). With a scheduler address, each chunk is a task of
``distributed.Client.submit`` on an existing cluster: the workers import gyrosim and return the chunk's columns
(numpy arrays, about 200 bytes per sample), and this process writes the files. Writing here keeps the output where
the user asked for it whether or not the workers share a file system, makes a file appear once per chunk however
often Dask ran the task (a worker lost mid-task has its tasks re-run by the scheduler; only the result that arrives
is written), and lets ``--resume`` trust what it finds. At most a window of tasks is in flight (four per worker
thread, at least 64), so neither side holds the sweep in memory.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import ConfigError, GyrosimError
from .interrupt import check as check_interrupt
from .interrupt import deferred
from .runner import run_chunk
from .spec import SweepSpec, build_spec
from .store import prepare_output, read_manifest, require_pyarrow, schema, write_chunk

__all__ = ["run_sweep", "SweepResult", "run_chunks_local", "run_chunks_dask"]


@dataclass
class SweepResult:
    """What a sweep did: the folder, its samples and chunks, the chunks and samples computed now (the others were
    there already: ``--resume``), the samples computed now that blew up, the wall time and where it ran."""

    output: Path
    samples: int
    chunks: int
    computed_chunks: int
    computed_samples: int
    blew_up: int
    seconds: float
    where: str
    spec: SweepSpec

    def format(self) -> str:
        done = (f"{self.computed_chunks} of {self.chunks} chunks computed now" if self.computed_chunks != self.chunks
                else f"{self.chunks} chunk{'s' * (self.chunks != 1)}")
        rate = (f", {self.computed_samples / self.seconds:,.0f} samples/s"
                if self.seconds > 0 and self.computed_samples else "")
        return (f"wrote {self.output}: {self.samples:,} samples in {done} ({self.where}; {self.seconds:.2f} s"
                f"{rate}); {self.blew_up} of the {self.computed_samples:,} samples computed now blew up")


def run_chunks_local(spec: SweepSpec, todo, on_result) -> None:
    """Run the chunks ``todo`` one after another in this process; ``on_result(k, columns)`` for each."""
    for k in todo:
        check_interrupt()
        on_result(k, run_chunk(spec, k))


def _connect(scheduler):
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - distributed is in the sweep and test extras
        raise GyrosimError("--scheduler needs dask.distributed, which is not installed: "
                           "pip install 'gyrosim[sweep]'") from None
    if not isinstance(scheduler, str):
        return scheduler, False  # a Client given by the caller (Python API)
    try:
        return Client(scheduler, timeout="10s", set_as_default=False), True
    except (OSError, TimeoutError, ValueError) as e:
        raise GyrosimError(f"--scheduler {scheduler!r}: cannot connect to a Dask scheduler there ({e}); start one "
                           "with `dask scheduler` and workers with `dask worker ADDRESS`") from None


def run_chunks_dask(spec: SweepSpec, todo, on_result, client) -> None:
    """Run the chunks ``todo`` as tasks through ``client`` (a ``distributed.Client``); ``on_result(k, columns)`` in
    this process as each result arrives. Every chunk's task runs until it succeeds once: the scheduler re-runs the
    tasks of a worker that dies (up to its ``allowed-failures``); an error raised by the task itself ends the sweep
    with that error."""
    from distributed import as_completed

    nthreads = sum(client.nthreads().values())
    window = max(64, 4 * nthreads)
    token = spec.token()
    pending = iter(todo)
    chunk_of = {}

    def submit():
        k = next(pending, None)
        if k is None:
            return None
        f = client.submit(run_chunk, spec, k, key=f"gyrosim-sweep-{token}-{k}", pure=False)
        chunk_of[f.key] = k
        return f

    inflight = {}
    for _ in range(window):
        f = submit()
        if f is None:
            break
        inflight[f.key] = f
    # with_results: the results are gathered in the background while this thread writes files
    ac = as_completed(list(inflight.values()), with_results=True, loop=client.loop)
    try:
        while True:
            # wait in steps, acting on a Ctrl-C between them (sweep/interrupt.py: a wait inside next() would not)
            while not ac.has_ready() and not ac.is_empty():
                check_interrupt()
                time.sleep(0.05)
            try:
                fut, cols = next(ac)
            except StopIteration:
                break
            except GyrosimError:
                raise
            except Exception as e:  # e.g. KilledWorker: a worker died on a task more than allowed-failures times
                raise GyrosimError(f"a chunk failed on the Dask cluster: {type(e).__name__}: {e}") from e
            k = chunk_of.pop(fut.key)
            del inflight[fut.key]
            fut.release()
            on_result(k, cols)
            nxt = submit()
            if nxt is not None:
                inflight[nxt.key] = nxt
                ac.add(nxt)
    except BaseException:
        client.cancel(list(inflight.values()))
        raise


def run_sweep(scene=None, *, samples=None, vary=None, set=None, integrator=None, max_step=None,  # noqa: A002
              stop_time=None, output_interval=None, seed=None, output, scheduler=None, chunk_size=None,
              resume: bool = False, progress: bool = False, lyapunov: bool | None = None) -> SweepResult:
    """Run a sweep and write its Parquet dataset to ``output`` (see :mod:`gyrosim.sweep`).

    Every check runs before any work (:func:`gyrosim.sweep.spec.build_spec`); then the chunks not yet in
    ``output`` run in this process or (``scheduler``: an address or a ``distributed.Client``) on a Dask cluster.
    ``lyapunov``: add each sample's largest Lyapunov exponent (column ``lyapunov``, 1/s; about twice the work).

    Examples
    --------
    >>> import tempfile, pyarrow.parquet as pq
    >>> d = tempfile.mkdtemp() + "/sweep"
    >>> r = run_sweep("free_body", samples=100, vary=["omega_x=uniform(0.5,1.5)"], stop_time=1.0, output=d)
    >>> t = pq.read_table(d)
    >>> t.num_rows, "omega_x_start" in t.column_names, "max_L_drift" in t.column_names
    (100, True, True)
    """
    with deferred():  # Ctrl-C acted on between pieces of work, never lost (sweep/interrupt.py)
        return _run_sweep(scene, samples=samples, vary=vary, set=set, integrator=integrator, max_step=max_step,
                          stop_time=stop_time, output_interval=output_interval, seed=seed, output=output,
                          scheduler=scheduler, chunk_size=chunk_size, resume=resume, progress=progress,
                          lyapunov=lyapunov)


def _run_sweep(scene, *, samples, vary, set, integrator, max_step, stop_time, output_interval,  # noqa: A002
               seed, output, scheduler, chunk_size, resume, progress, lyapunov) -> SweepResult:
    require_pyarrow()
    out = Path(output)
    if resume and chunk_size is None and out.is_dir():
        old = read_manifest(out)
        if old is not None:
            chunk_size = old.get("chunk_size")
    spec = build_spec(scene, samples=samples, vary=vary, set=set, integrator=integrator, max_step=max_step,
                      stop_time=stop_time, output_interval=output_interval, seed=seed, chunk_size=chunk_size,
                      lyapunov=lyapunov)
    if scheduler is not None and isinstance(scheduler, str) and "://" not in scheduler:
        raise ConfigError("--scheduler", scheduler, "a Dask scheduler address such as tcp://127.0.0.1:8786")
    client, own = _connect(scheduler) if scheduler is not None else (None, False)
    try:
        return _run(spec, out, resume, client, scheduler, progress)
    finally:
        if own:
            client.close()


def _run(spec, out, resume, client, scheduler, progress) -> SweepResult:
    have = prepare_output(out, spec, resume)
    todo = [k for k in range(spec.n_chunks) if k not in have]
    sch = schema(spec)
    blew = 0
    done_chunks = []
    bar = None
    if progress and todo:
        from tqdm import tqdm

        done0 = sum(b - a for a, b in (spec.chunk_bounds(k) for k in have))
        bar = tqdm(total=spec.samples, initial=done0, unit="sample", unit_scale=True, desc="sweep", file=sys.stderr,
                   smoothing=0.1, dynamic_ncols=True)

    def on_result(k, cols):
        nonlocal blew
        write_chunk(out, k, cols, sch)
        blew += int(cols["blew_up"].sum())
        done_chunks.append(k)
        if bar is not None:
            a, b = spec.chunk_bounds(k)
            bar.update(b - a)

    t0 = time.perf_counter()
    try:
        if client is None:
            where = "in this process"
            run_chunks_local(spec, todo, on_result)
        else:
            where = f"Dask at {scheduler}" if isinstance(scheduler, str) else "Dask"
            run_chunks_dask(spec, todo, on_result, client)
    finally:
        if bar is not None:
            bar.close()
    n_done = sum(b - a for a, b in (spec.chunk_bounds(k) for k in done_chunks))
    return SweepResult(out, spec.samples, spec.n_chunks, len(done_chunks), n_done, blew, time.perf_counter() - t0,
                       where, spec)
