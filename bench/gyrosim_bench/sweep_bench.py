"""Sweep benchmark (``gyrosim bench --only sweep``): what the sweep machinery costs, in this process and on Dask.

``run(out_dir, quick=False)`` writes ``sweep.md`` (tables) and ``sweep.json`` (every number) into ``out_dir`` and
returns a one-line summary. Stand-alone, from the checkout root:
``PYTHONPATH=bench python -m gyrosim_bench.sweep_bench [OUT_DIR] [--quick]``.

* **local**: sample-steps per second of ``gyrosim sweep`` (draws, checks, one Model per chunk, the drift
  reductions, Parquet files) against the plain many-body loop on the same scene: Models of as many bodies as a
  chunk has, ``Model.trajectory`` over the same output grid in the same blocks, nothing else; with the outputs the
  sweep reads (``angles=False``: L and the energy balance at every output point), with none (bare stepping), and
  as one Model of every body.
* **cluster**: a scheduler and two one-thread workers started with ``dask scheduler`` / ``dask worker`` on
  127.0.0.1 (this machine's cores), the same sweep through ``--scheduler`` against the local run.
* **per-task overhead**: sweeps of one-sample chunks of one output interval (no work to speak of): wall time per
  chunk, in the process (a Model and a Parquet file per chunk) and on the cluster (plus Dask's task round trip).
* **chunk size**: the same sweep with several chunk sizes, locally and on the cluster.

Wall-clock times (every core is used), the best of interleaved rounds (each round runs every measurement once).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

__all__ = ["run", "DaskProcesses"]

SCENE = "gyroscope"
#: The folder that holds gyrosim_bench (the checkout's bench/): on the Dask processes' PYTHONPATH, because
#: ``run_on_scheduler(_worker_names)`` sends the function by reference and the scheduler imports it from there
BENCH_DIR = str(Path(__file__).resolve().parents[1])
VARY = ["omega_z=uniform(150,250)", "mass=uniform(0.4,0.6)"]


class DaskProcesses:
    """A scheduler and named workers started with Dask's own commands, each in its own process group, every address
    on 127.0.0.1 (``--host 127.0.0.1 --dashboard-address 127.0.0.1:0``). Used by this bench and the tests."""

    def __init__(self, work: Path, env: dict | None = None):
        self.work = Path(work)
        self.env = env
        self.procs: dict[str, subprocess.Popen] = {}
        self.address = None

    @staticmethod
    def command() -> list[str]:
        exe = Path(sys.executable).parent / "dask"
        return [str(exe)] if exe.exists() else [sys.executable, "-m", "dask"]

    def _start(self, name: str, args: list[str]) -> subprocess.Popen:
        env = dict(os.environ if self.env is None else self.env)
        env["PYTHONPATH"] = BENCH_DIR + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        with open(self.work / f"{name}.log", "w") as log:
            p = subprocess.Popen(self.command() + args, stdout=log, stderr=subprocess.STDOUT, env=env,
                                 start_new_session=True, cwd=self.work)
        self.procs[name] = p
        return p

    def start_scheduler(self, timeout: float = 60.0) -> str:
        f = self.work / "scheduler.json"
        self._start("scheduler", ["scheduler", "--host", "127.0.0.1", "--port", "0", "--dashboard-address",
                                  "127.0.0.1:0", "--scheduler-file", str(f), "--no-show"])
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                self.address = json.loads(f.read_text())["address"]
                return self.address
            except (OSError, ValueError, KeyError):
                time.sleep(0.05)
        raise RuntimeError("dask scheduler did not start: " + self.log("scheduler"))

    def start_worker(self, name: str, nthreads: int = 1) -> subprocess.Popen:
        return self._start(name, ["worker", self.address, "--host", "127.0.0.1", "--dashboard-address",
                                  "127.0.0.1:0", "--nthreads", str(nthreads), "--name", name, "--local-directory",
                                  str(self.work / name)])

    def client(self):
        from distributed import Client

        return Client(self.address, timeout="30s", set_as_default=False)

    def wait_for_workers(self, names, timeout: float = 60.0) -> dict:
        """{name: worker address} once every worker in ``names`` is registered."""
        with self.client() as c:
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                have = c.run_on_scheduler(_worker_names)
                if all(n in have for n in names):
                    return {n: have[n] for n in names}
                time.sleep(0.05)
        raise RuntimeError(f"workers {list(names)} did not register: " + " | ".join(self.log(n) for n in names))

    def kill(self, name: str) -> None:
        """SIGKILL a process group (a worker: its nanny and its worker process)."""
        p = self.procs.pop(name)
        os.killpg(p.pid, signal.SIGKILL)
        p.wait(timeout=30)

    def log(self, name: str) -> str:
        f = self.work / f"{name}.log"
        return f.read_text()[-3000:] if f.exists() else ""

    def stop(self) -> None:
        """SIGTERM the workers, then the scheduler (SIGKILL after 15 s)."""
        names = [n for n in self.procs if n != "scheduler"] + (["scheduler"] if "scheduler" in self.procs else [])
        for name in names:
            p = self.procs.pop(name)
            try:
                os.killpg(p.pid, signal.SIGTERM)
            except ProcessLookupError:
                continue
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=15)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def _worker_names(dask_scheduler=None) -> dict:
    """{worker name: address}, run on the scheduler (Client.scheduler_info lists only 5 workers since 2025.4)."""
    return {str(ws.name): addr for addr, ws in dask_scheduler.workers.items()}


def _plain(samples: int, stop_time: float, bodies: int, momentum: bool) -> float:
    """Seconds of the plain many-body loop over the sweep's grid: Models of ``bodies`` bodies (the scene's body
    replicated), one after another until ``samples`` bodies have run, each over the grid in the sweep's blocks."""
    from gyrosim.model import OUTPUT_NAMES, Model
    from gyrosim.scene import load_scene
    from gyrosim.sweep.runner import BLOCK_VALUES, _replicated

    sc = load_scene(SCENE)
    dt = sc.output_interval
    n = int(round(stop_time / dt))
    t0 = time.perf_counter()
    for a in range(0, samples, bodies):
        k = min(bodies, samples - a)
        m = Model(_replicated(sc, k), stop_time=stop_time)
        status = np.zeros(k, dtype=np.int32)
        block = max(1, BLOCK_VALUES // (len(OUTPUT_NAMES) * k))
        done = 0
        while done < n:
            j = min(block, n - done)
            m.trajectory(dt, j, angles=False, momentum=momentum, status=status)
            done += j
    return time.perf_counter() - t0


def _sweep(tmp: Path, samples: int, stop_time: float, chunk: int, scheduler=None, interval=None) -> float:
    from gyrosim.sweep.execute import run_sweep

    out = Path(tempfile.mkdtemp(dir=tmp)) / "s"
    t0 = time.perf_counter()
    run_sweep(SCENE, samples=samples, vary=VARY, stop_time=stop_time, output=out, chunk_size=chunk,
              scheduler=scheduler, output_interval=interval)
    dt = time.perf_counter() - t0
    shutil.rmtree(out.parent)
    return dt


def _steps_per_sample(stop_time: float) -> int:
    from gyrosim.core import _engine
    from gyrosim.scene import load_scene

    sc = load_scene(SCENE)
    return int(round(stop_time / sc.output_interval)) * int(_engine.substeps(sc.output_interval, sc.max_step))


def run(out_dir, quick: bool = False) -> str:
    """Run the measurements; write ``sweep.md`` and ``sweep.json`` into ``out_dir``; return a summary line."""
    from gyrosim.core import _engine

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    samples = 4000 if quick else 20_000
    stop = 0.5 if quick else 1.0
    chunk = 2000
    rounds = 2 if quick else 3
    sizes = [200, 1000, 2000, 4000] if quick else [100, 500, 2000, 10_000]
    n_tiny = 200 if quick else 500
    steps = _steps_per_sample(stop)
    ss = samples * steps
    res = {"scene": SCENE, "vary": VARY, "samples": samples, "stop_time": stop, "steps_per_sample": steps,
           "chunk_size": chunk, "threads": int(_engine.max_threads()), "cpus": os.cpu_count(), "quick": quick,
           "rounds": rounds}
    try:
        import distributed  # noqa: F401

        have_dask = True
    except ImportError:  # pragma: no cover - distributed is in the sweep and test extras
        have_dask = False
    t: dict = {}
    with tempfile.TemporaryDirectory(prefix="gyrosim-sweep-bench-") as tmp_name:
        tmp = Path(tmp_name)
        (tmp / "dask").mkdir()
        with DaskProcesses(tmp / "dask") as cluster:
            addr = None
            if have_dask:
                addr = cluster.start_scheduler()
                cluster.start_worker("w1")
                cluster.start_worker("w2")
                cluster.wait_for_workers(["w1", "w2"])
                _sweep(tmp, 200, 0.05, 100, addr)  # warm-up: the workers import gyrosim
            _sweep(tmp, 200, 0.05, 100)  # warm-up (imports, caches)
            plan = [("plain", lambda: _plain(samples, stop, chunk, True)),
                    ("bare", lambda: _plain(samples, stop, chunk, False)),
                    ("plain_one_model", lambda: _plain(samples, stop, samples, True)),
                    ("overhead_local", lambda: _sweep(tmp, n_tiny, 0.01, 1))]
            plan += [(("local", k), lambda k=k: _sweep(tmp, samples, stop, k)) for k in sizes]
            if addr:
                plan.append(("overhead_cluster", lambda: _sweep(tmp, n_tiny, 0.01, 1, addr)))
                plan += [(("cluster", k), lambda k=k: _sweep(tmp, samples, stop, k, addr)) for k in sizes]
            for _ in range(rounds):  # interleaved rounds, the best of each
                for key, fn in plan:
                    t.setdefault(key, []).append(fn())
    best = {k: min(v) for k, v in t.items()}
    loc = best[("local", chunk)]
    res["local"] = {"plain_loop_s": best["plain"], "bare_loop_s": best["bare"], "sweep_s": loc,
                    "plain_one_model_s": best["plain_one_model"],
                    "plain_sample_steps_per_s": ss / best["plain"], "bare_sample_steps_per_s": ss / best["bare"],
                    "sweep_sample_steps_per_s": ss / loc, "ratio_vs_plain": best["plain"] / loc,
                    "ratio_vs_bare": best["bare"] / loc}
    res["overhead"] = {"tasks": n_tiny, "local_s_per_chunk": best["overhead_local"] / n_tiny}
    res["chunks"] = [{"chunk_size": k, "local_s": best[("local", k)]} for k in sizes]
    if addr:
        cl = best[("cluster", chunk)]
        res["cluster"] = {"workers": 2, "threads_per_worker": 1, "sweep_s": cl, "sample_steps_per_s": ss / cl,
                          "ratio_vs_local": loc / cl}
        res["overhead"]["cluster_s_per_chunk"] = best["overhead_cluster"] / n_tiny
        for row in res["chunks"]:
            row["cluster_s"] = best[("cluster", row["chunk_size"])]
        # one worker thread's seconds per sample, and the chunk size for 100 workers
        res["estimate_100_workers"] = _estimate(cl * 2 / samples, res["overhead"]["cluster_s_per_chunk"], 100)
    else:
        res["cluster"] = {"skipped": "dask.distributed is not installed"}
    res["times"] = {str(k): v for k, v in t.items()}
    (out / "sweep.json").write_text(json.dumps(res, indent=1))
    (out / "sweep.md").write_text(_table(res))
    lo = res["local"]
    summary = (f"local sweep {lo['sweep_sample_steps_per_s']:.3g} sample-steps/s = {lo['ratio_vs_plain']:.2f}x "
               f"the plain loop ({lo['ratio_vs_bare']:.2f}x bare stepping)")
    if "ratio_vs_local" in res["cluster"]:
        summary += (f"; 2-worker Dask cluster {res['cluster']['ratio_vs_local']:.2f}x local; per-task overhead "
                    f"{res['overhead']['cluster_s_per_chunk'] * 1e3:.1f} ms on Dask, "
                    f"{res['overhead']['local_s_per_chunk'] * 1e3:.1f} ms in process")
    return summary


def _estimate(c1: float, o: float, workers: int) -> dict:
    """Chunk sizes for ``workers`` one-thread workers, from the seconds per sample of one worker thread ``c1`` and
    the per-task overhead ``o`` (s, serial in the client and scheduler): tasks finish at ``workers / (K c1)`` per
    second and the client and scheduler keep up with ``1 / o``; at most 10% of their capacity needs
    ``K >= 10 workers o / c1``; at least 10 tasks per worker (load balance and a lost worker costing little) needs
    ``N >= 10 workers K``."""
    k_min = 10 * workers * o / c1
    return {"workers": workers, "s_per_sample_per_thread": c1, "overhead_s_per_task": o,
            "min_chunk_size": int(np.ceil(k_min)), "min_samples_for_10_tasks_per_worker": int(np.ceil(k_min)) * 10 *
            workers}


def _table(res: dict) -> str:
    loc = res["local"]
    lines = [
        f"## Sweeps ({res['scene']}, {res['samples']:,} samples of {res['steps_per_sample']} internal steps "
        f"(splitting, max_step 1e-3 s, stop_time {res['stop_time']} s), vary {', '.join(res['vary'])}; "
        f"{res['cpus']} CPUs, engine threads {res['threads']})",
        "",
        "| run | wall (s) | sample-steps/s | ratio |",
        "|---|---|---|---|",
        f"| plain many-body loop: Models of {res['chunk_size']} bodies, trajectory (L and energy balance at each "
        f"output point) | {loc['plain_loop_s']:.3f} | {loc['plain_sample_steps_per_s']:.3g} | 1 |",
        f"| bare stepping: the same without derived outputs | {loc['bare_loop_s']:.3f} | "
        f"{loc['bare_sample_steps_per_s']:.3g} | {loc['plain_loop_s'] / loc['bare_loop_s']:.2f}x plain |",
        f"| the plain loop as one Model of all {res['samples']:,} bodies | {loc['plain_one_model_s']:.3f} | "
        f"{res['samples'] * res['steps_per_sample'] / loc['plain_one_model_s']:.3g} | "
        f"{loc['plain_loop_s'] / loc['plain_one_model_s']:.2f}x plain |",
        f"| `gyrosim sweep`, in process, chunks of {res['chunk_size']} | {loc['sweep_s']:.3f} | "
        f"{loc['sweep_sample_steps_per_s']:.3g} | {loc['ratio_vs_plain']:.2f}x plain, {loc['ratio_vs_bare']:.2f}x "
        "bare |",
    ]
    cl = res.get("cluster", {})
    if "sweep_s" in cl:
        lines.append(f"| `gyrosim sweep --scheduler`, 2 workers x 1 thread on this machine, chunks of "
                     f"{res['chunk_size']} | {cl['sweep_s']:.3f} | {cl['sample_steps_per_s']:.3g} | "
                     f"{cl['ratio_vs_local']:.2f}x local |")
    elif cl:
        lines.append(f"| cluster | - | - | {cl.get('skipped')} |")
    ov = res["overhead"]
    lines += ["", f"Per-task overhead ({ov['tasks']} one-sample chunks of one output interval):", "",
              "| where | ms per chunk |", "|---|---|",
              f"| in process (a Model and a Parquet file per chunk) | {ov['local_s_per_chunk'] * 1e3:.2f} |"]
    if "cluster_s_per_chunk" in ov:
        lines.append(f"| Dask, 2 workers (plus the task's round trip through the scheduler) | "
                     f"{ov['cluster_s_per_chunk'] * 1e3:.2f} |")
    lines += ["", "Chunk size (the same sweep; wall seconds):", "", "| chunk size | chunks | in process | Dask, 2 "
              "workers |", "|---|---|---|---|"]
    for row in res["chunks"]:
        k = row["chunk_size"]
        lines.append(f"| {k:,} | {-(-res['samples'] // k)} | {row['local_s']:.3f} | "
                     + (f"{row['cluster_s']:.3f} |" if "cluster_s" in row else "- |"))
    est = res.get("estimate_100_workers")
    if est:
        per_sample = est["s_per_sample_per_thread"] * 1e3
        per_task = est["overhead_s_per_task"] * 1e3
        lines += ["", f"For {est['workers']} one-thread workers (this sample: {per_sample:.3f} ms per sample and "
                  f"thread; {per_task:.2f} ms per task): chunks of at least {est['min_chunk_size']:,} samples keep "
                  f"the client and scheduler under 10% busy, and {est['min_samples_for_10_tasks_per_worker']:,} "
                  "samples give 10 such chunks per worker."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--quick"]
    target = args[0] if args else "out/bench"
    print(run(target, quick="--quick" in sys.argv))
    print((Path(target) / "sweep.md").read_text())
