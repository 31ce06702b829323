"""Speed and memory of the Python package against the same work in Rust (issue 34).

    python python/bench.py [--no-rust] [--runs N]

1. A 4096² fill with ``out=`` of the bundled AFM map's RPN bank (``tiles/di-6.npy``,
   seed 1, placed with seed 3, at (-123456.5, 987654.25)): criterion's
   ``fill/step1_4096`` fills the same region of the same bank in Rust.
2. ``Surface.height`` on 10⁶ random points within ±10⁶ px from numpy arrays: criterion's
   ``sample_1e6/height_random_points_loop`` is the Rust loop over as many points.
3. Memory: peak RSS and tracemalloc's peak while filling into ``out=``, against the
   array's size.

Unless ``--no-rust``, it runs the two criterion benches (``cargo bench``, which compiles
them if needed) in the same run, in rounds interleaved with the Python timings, and
prints the median of the rounds' ratios: on a shared machine whose speed drifts by
±10% from minute to minute, a round's two figures are taken close together. Medians
throughout.
"""

import argparse
import json
import resource
import statistics
import subprocess
import time
import tracemalloc
from pathlib import Path

import numpy as np

import surftile

REPO = Path(__file__).resolve().parents[1]
SIDE = 4096
ORIGIN = (-123456.5, 987654.25)
POINTS = 1_000_000


def criterion_median(bench, group, name):
    """Runs one criterion bench and returns its median in seconds."""
    subprocess.run(
        ["cargo", "bench", "--bench", bench, "--", f"{group}/{name}"],
        cwd=REPO,
        check=True,
        stdout=subprocess.DEVNULL,
    )
    path = REPO / "target" / "criterion" / group / name / "new" / "estimates.json"
    return json.loads(path.read_text())["median"]["point_estimate"] * 1e-9


def median_time(f, runs):
    times = []
    for _ in range(runs):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def peak_rss_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-rust", action="store_true", help="skip the criterion benches")
    parser.add_argument("--runs", type=int, default=15, help="timed Python runs per figure and round")
    parser.add_argument(
        "--rounds", type=int, default=5,
        help="rounds of criterion then Python, interleaved so that a drift of the machine's speed hits both",
    )
    args = parser.parse_args()

    surface = surftile.bake(REPO / "tiles" / "di-6.npy", method="rpn", seed=1).surface(3)
    out = np.ones((SIDE, SIDE), np.float32)  # pages touched: RSS holds the array
    surface.fill(*ORIGIN, SIDE, SIDE, out=out)
    rng = np.random.default_rng(9)
    xs = rng.uniform(-1e6, 1e6, POINTS)
    ys = rng.uniform(-1e6, 1e6, POINTS)
    surface.height(xs, ys)

    fills, heights, rust_fills, rust_heights = [], [], [], []
    rss_before = peak_rss_bytes()
    for _ in range(args.rounds):
        if not args.no_rust:
            rust_fills.append(criterion_median("fill", "fill", f"step1_{SIDE}"))
        fills.append(median_time(lambda: surface.fill(*ORIGIN, SIDE, SIDE, out=out), args.runs))
        if not args.no_rust:
            rust_heights.append(
                criterion_median("sample", "sample_1e6", "height_random_points_loop")
            )
        heights.append(median_time(lambda: surface.height(xs, ys), args.runs))
    rss_growth = peak_rss_bytes() - rss_before
    tracemalloc.start()
    surface.fill(*ORIGIN, SIDE, SIDE, out=out)
    traced_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()

    def show(what, py_times, rust_times, rust_name, unit_count, unit):
        p = statistics.median(py_times)
        print(f"{what}: Python {p * 1e3:7.1f} ms ({unit_count / p / 1e6:.2f} M {unit}/s)")
        if rust_times:
            r = statistics.median(rust_times)
            ratios = [a / b for a, b in zip(py_times, rust_times)]
            rounds = ", ".join(f"{x:.3f}" for x in ratios)
            print(
                f"{'':{len(what)}}  Rust   {r * 1e3:7.1f} ms ({rust_name}); Python / Rust: "
                f"{statistics.median(ratios):.3f}, the median of the rounds' ratios ({rounds})"
            )

    show(f"fill {SIDE}² out=", fills, rust_fills, f"fill/step1_{SIDE}", SIDE * SIDE, "samples")
    show(
        "height 10⁶ points", heights, rust_heights,
        "sample_1e6/height_random_points_loop", POINTS, "points",
    )
    print(
        f"memory, fill into out= ({out.nbytes / 2**20:.0f} MiB array): peak RSS grew "
        f"{rss_growth / 2**20:.1f} MiB over the timed calls; tracemalloc peak of one fill "
        f"{traced_peak / 2**10:.1f} KiB"
    )


if __name__ == "__main__":
    main()
