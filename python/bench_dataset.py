"""Dataset throughput (issue 35): samples/s of the same spec written locally and
through Ray with 1 and 2 workers, next to the bare fill of the same regions.

    python python/bench_dataset.py [--runs N]

The spec is benches/dataset.rs's: 512² samples of the bundled AFM map's RPN bank
(tiles/di-6.npy baked with seed 1 by the CLI) with scratches and dents and their mask,
heights, mask and JSON per sample; here 64 samples in 8 shards of 8, so that two Ray
workers have work to share. Each figure is the median of N runs (default 3) into a
fresh folder:

- ``cli``: ``surftile dataset`` (every core, one stream of shards);
- ``local``: ``surftile.dataset.generate(engine="local")`` (the same stream);
- ``ray-1``, ``ray-2``: ``generate(engine="ray")`` on a Ray head started here on
  loopback with 1 or 2 CPUs (one task per shard, one thread per task), this process
  connected to it once; the cluster's start and a first warm-up run (its workers'
  start) are not timed, task scheduling is;
- ``bare-fill``: ``Surface.fill`` of the same 64 regions (every core), no defects, no
  files: the baseline.
"""

import argparse
import json
import os
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import surftile
import surftile.dataset as ds

REPO = Path(__file__).resolve().parents[1]


def spec_text(bank):
    bench = (REPO / "benches" / "dataset.rs").read_text()
    text = bench.split('const SPEC: &str = r#"', 1)[1].split('"#;', 1)[0]
    return (text.replace("samples_per_shard = 16", "samples_per_shard = 8")
            .replace('path = "di-6.bank"', f'path = "{bank}"'))


def cli():
    exe = os.environ.get("SURFTILE_BIN") or REPO / "target" / "release" / "surftile"
    return str(exe)


def timed(run, runs):
    times = []
    for _ in range(runs):
        times.append(run())
    return statistics.median(times)


def ray_head(cpus):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    ray = str(Path(sys.executable).with_name("ray"))
    subprocess.run([ray, "start", "--head", "--node-ip-address=127.0.0.1", f"--port={port}",
                    f"--num-cpus={cpus}", "--object-store-memory=200000000",
                    "--include-dashboard=false", "--disable-usage-stats"],
                   check=True, capture_output=True)
    return f"127.0.0.1:{port}", lambda: subprocess.run([ray, "stop", "--force"],
                                                       capture_output=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    os.environ.update(RAY_AUTH_MODE="disabled", RAY_USAGE_STATS_ENABLED="0")
    work = Path(tempfile.mkdtemp(prefix="surftile-bench-dataset-"))
    try:
        bank = work / "di-6.bank"
        subprocess.run([cli(), "bake", REPO / "tiles" / "di-6.npy", "--seed", "1",
                        "--out", bank], check=True, capture_output=True)
        spec = work / "spec.toml"
        spec.write_text(spec_text(bank))
        dataset = ds.Dataset(str(spec))
        n = dataset.samples
        results = {}

        def fresh(name):
            out = work / name
            shutil.rmtree(out, ignore_errors=True)
            return out

        def run_cli():
            out = fresh("cli")
            t = time.perf_counter()
            subprocess.run([cli(), "dataset", spec, "--out", out], check=True,
                           capture_output=True)
            return time.perf_counter() - t

        def run_generate(engine, address=None):
            def run():
                out = fresh(engine)
                t = time.perf_counter()
                ds.generate(spec, out, engine=engine, address=address, progress=False)
                return time.perf_counter() - t
            return run

        # The baseline: the same regions and seeds, filled bare.
        source = surftile.open(bank)
        draws = [dataset.sample(k)["meta"] for k in range(n)]

        def bare():
            t = time.perf_counter()
            for m in draws:
                r = m["region"]
                source.surface(m["seed"]).fill(r["x"], r["y"], r["width"], r["height"])
            return time.perf_counter() - t

        results["bare-fill"] = timed(bare, args.runs)
        results["cli"] = timed(run_cli, args.runs)
        results["local"] = timed(run_generate("local"), args.runs)
        reference = sorted((work / "cli").glob("shard-*.tar"))
        for cpus in (1, 2):
            address, stop = ray_head(cpus)
            try:
                # One driver connection for the runs, as a session would hold it (each
                # new connection is a new Ray job, whose workers start afresh).
                import ray
                ray.init(address=address, log_to_driver=False)
                run = run_generate("ray")
                run()  # workers start and import surftile: not timed
                results[f"ray-{cpus}"] = timed(run, args.runs)
            finally:
                ray.shutdown()
                stop()
            same = all(p.read_bytes() == (work / "ray" / p.name).read_bytes() for p in reference)
            assert same, "Ray's shards differ from the CLI's"
        report = {name: {"seconds": round(t, 3), "samples_per_s": round(n / t, 1),
                         "vs_bare_fill": round(results["bare-fill"] / t, 3)}
                  for name, t in results.items()}
        print(json.dumps({"samples": n, "size": [512, 512], "runs": args.runs,
                          "cpus": os.cpu_count(), "results": report}, indent=2))
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
