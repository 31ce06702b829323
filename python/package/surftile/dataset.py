"""Training datasets: WebDataset tar shards of samples drawn from a spec.

A spec (TOML) names sources, imperfection layers and defects with their probabilities
and ranges; sample k is a pure function of (spec, k), so any shard can be made on any
machine, in any order, with the same bytes as ``surftile dataset SPEC --out DIR``::

    import surftile.dataset
    surftile.dataset.generate("tiles/dataset/example.toml", "out")          # this machine
    surftile.dataset.generate("spec.toml", "/shared/out", engine="ray",     # a Ray cluster
                              address="auto")

Each shard is written to a temporary name and renamed, so a task that dies leaves no
partial shard, and a rerun skips the complete ones. See docs/dataset.md.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any, Callable, Iterable, Optional

from ._surftile import Dataset

__all__ = ["Dataset", "generate", "write_shard"]


def write_shard(spec: "str | os.PathLike[str]", index: int, out: "str | os.PathLike[str]",
                *, threads: Optional[int] = None) -> dict:
    """Writes shard ``index`` of the dataset ``spec`` into the folder ``out``.

    The bytes equal the CLI's for the same spec and shard, whatever ``threads`` (None:
    every core). ``out`` must exist; a ``dataset.json`` there of another spec is
    refused. Returns ``{"shard", "samples", "bytes"}``.
    """
    return Dataset(os.fspath(spec)).write_shard(index, os.fspath(out), threads)


def _shard_range(dataset: Dataset, shards: Optional[Iterable[int]]) -> range:
    if shards is None:
        return range(0, dataset.shards)
    if isinstance(shards, range) and shards.step == 1:
        return shards
    listed = sorted(set(int(s) for s in shards))
    if not listed or listed != list(range(listed[0], listed[-1] + 1)):
        raise ValueError(
            f"invalid shards = {shards!r}: expected None or a contiguous range of shard numbers"
        )
    return range(listed[0], listed[-1] + 1)


def _report(progress: "bool | Callable[[dict], Any]", event: dict) -> None:
    if callable(progress):
        progress(event)
    elif progress:
        rate = event["samples"] / max(event["seconds"], 1e-9)
        print(
            f"dataset: shard {event['shard']} done, {event['done']}/{event['total']} shards, "
            f"{rate:.1f} samples/s",
            file=sys.stderr,
        )


_OPENED: dict = {}


def _ray_write(spec: str, index: int, out: str, threads: int) -> dict:
    # A worker runs many tasks of one spec: it opens the spec (sources, layers, hash)
    # once, and again only when the file changes.
    stat = os.stat(spec)
    key = (spec, stat.st_mtime_ns, stat.st_size)
    dataset = _OPENED.get(key)
    if dataset is None:
        _OPENED.clear()
        dataset = _OPENED[key] = Dataset(spec)
    return dataset.write_shard(index, out, threads)


def generate(
    spec: "str | os.PathLike[str]",
    out: "str | os.PathLike[str]",
    *,
    engine: str = "local",
    shards: Optional[Iterable[int]] = None,
    address: Optional[str] = None,
    workers: Optional[int] = None,
    force: bool = False,
    retries: int = 3,
    progress: "bool | Callable[[dict], Any]" = True,
) -> dict:
    """Writes the shards of ``spec`` (all, or the contiguous ``shards``) into ``out``.

    - ``engine="local"``: on this machine, each shard's samples on ``workers`` threads
      (None: every core). Needs nothing beyond this package.
    - ``engine="ray"``: one Ray task per shard (``pip install "./python[ray]"``), on the
      cluster at ``address`` (``"auto"``, ``"ray://host:10001"``, ``"host:6379"``), or
      on a local Ray started for the job with ``workers`` CPUs when ``address`` is None
      and Ray is not yet initialised. Each task renders its shard on one thread. Tasks
      are retried up to ``retries`` times: a shard is idempotent and written
      atomically. ``spec``, its sources and ``out`` must be at the same paths on every
      node (shared storage).

    Complete shards are kept, ``dataset.json`` is written first, and a ``dataset.json``
    of another spec is refused unless ``force`` (which removes its shards).
    ``progress``: True prints a line per shard to stderr; a callable gets a dict per
    shard (shard, done, total, samples, seconds).

    Returns ``{"written": [...], "complete": [...], "broken": [...], "samples": n,
    "seconds": t}``. Raises ``RuntimeError`` naming the shards whose tasks failed,
    after the others finished (their temporary files removed): rerun to complete.
    """
    if engine not in ("local", "ray"):
        raise ValueError(f'invalid engine = {engine!r}: expected "local" or "ray"')
    if workers is not None and not (isinstance(workers, int) and 1 <= workers <= 1024):
        raise ValueError(f"invalid workers = {workers!r}: expected 1 to 1024, or None")
    if not (isinstance(retries, int) and 0 <= retries <= 100):
        raise ValueError(f"invalid retries = {retries!r}: expected 0 to 100")
    spec = os.path.abspath(os.fspath(spec))
    out = os.path.abspath(os.fspath(out))
    dataset = Dataset(spec)
    span = _shard_range(dataset, shards)
    prepared = dataset.prepare(out, span.start, span.stop, force)
    todo = prepared["todo"]
    start = time.monotonic()
    written: list = []
    failed: dict = {}
    samples = 0

    def finished(result: dict) -> None:
        nonlocal samples
        written.append(result["shard"])
        samples += result["samples"]
        _report(progress, {
            "shard": result["shard"], "done": len(written), "total": len(todo),
            "samples": samples, "seconds": time.monotonic() - start,
        })

    if engine == "local":
        # One stream over the shards, as the CLI writes them; shards are reported as
        # they complete (the callback runs between samples, with the GIL).
        sizes = {}
        for s in todo:
            first, end = dataset.shard_samples(s)
            sizes[s] = end - first

        def report(samples_done: int, shards_done: int) -> None:
            while len(written) < shards_done:
                s = todo[len(written)]
                finished({"shard": s, "samples": sizes[s]})

        if todo:
            dataset.write_shards(todo, out, workers, report)
            report(0, len(todo))
    else:
        failed = _run_ray(spec, out, todo, address, workers, retries, finished)
        dataset.remove_temporaries(out, span.start, span.stop)
    if failed:
        names = ", ".join(f"{s} ({type(e).__name__})" for s, e in sorted(failed.items()))
        raise RuntimeError(
            f"dataset: {len(failed)} shard(s) failed: {names}; the others are complete, "
            "run generate() again to write the rest"
        )
    return {
        "written": sorted(written),
        "complete": prepared["complete"],
        "broken": prepared["broken"],
        "samples": samples,
        "seconds": time.monotonic() - start,
    }


def _run_ray(spec: str, out: str, todo: list, address: Optional[str],
             workers: Optional[int], retries: int,
             finished: Callable[[dict], None]) -> dict:
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            'engine="ray" needs Ray: pip install "surftile[ray]" (or pip install ray)'
        ) from e
    started = False
    if not ray.is_initialized():
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
        started = True
    failed: dict = {}
    try:
        task = ray.remote(num_cpus=1, max_retries=retries)(_ray_write)
        pending = {task.remote(spec, s, out, 1): s for s in todo}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                s = pending.pop(ref)
                try:
                    finished(ray.get(ref))
                except Exception as e:  # a task that failed past its retries
                    failed[s] = e
    finally:
        if started:
            ray.shutdown()
    return failed
