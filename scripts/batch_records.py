#!/usr/bin/env python3
"""Re-processes archived recordings into the inspection records on a cluster: each
recording (`*.rfrec`, made with `rollfuse stream --record`) is played back through the
Python package (`rollfuse.stream('replay:FILE', records=DB)`) on a worker of a Dask or
Ray cluster, its strip written under OUT and its roll recorded in DB (a SQLite file all
workers share, or a `postgres://` URL). A recording processed again replaces its roll's
record, so a batch can be re-run after a failure or a better detector.

With --workers 1,2 it runs the batch on a local cluster of each size in turn (the same
recordings into fresh records each time) and prints rolls per second for each.

    python3 scripts/batch_records.py RECORDINGS_DIR --records out/records.db \
        --out out/batch --engine dask --workers 1,2
"""

import argparse
import glob
import os
import shutil
import sys
import time


def process(recording, out_root, records, line):
    """One recording played back into its strip and its roll's record; its tile count.
    Runs on a worker."""
    import rollfuse

    stem = os.path.splitext(os.path.basename(recording))[0]
    out = os.path.join(out_root, stem)
    if os.path.isdir(out):
        # The strip of an earlier run of this recording: its record is replaced too.
        shutil.rmtree(out)
    session = rollfuse.stream(f"replay:{recording}", out=out, records=records, line=line)
    tiles = sum(1 for _ in session)
    return stem, tiles


def warm_up():
    """Loads the package on a worker."""
    import rollfuse  # noqa: F401


def run_dask(recordings, workers, out, records, line):
    from dask.distributed import Client, LocalCluster

    # Processes, one thread each: the package releases the GIL, but a process a worker is
    # what a cluster of machines gives.
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        client.run(warm_up)  # every worker up, the package loaded, before the clock starts
        started = time.perf_counter()
        futures = [client.submit(process, r, out, records, line, pure=False)
                   for r in recordings]
        results = client.gather(futures)
        return results, time.perf_counter() - started


def run_ray(recordings, workers, out, records, line):
    import ray

    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    try:
        remote = ray.remote(num_cpus=1)(process)
        # Every worker up, the package loaded, before the clock starts.
        ray.get([ray.remote(num_cpus=1)(warm_up).remote() for _ in range(workers)])
        started = time.perf_counter()
        results = ray.get([remote.remote(r, out, records, line) for r in recordings])
        return results, time.perf_counter() - started
    finally:
        ray.shutdown()


def fresh(path):
    """Removes a SQLite file (with its WAL) or a folder left by an earlier size's run."""
    for p in (path, path + "-wal", path + "-shm"):
        if os.path.isdir(p):
            shutil.rmtree(p)
        elif os.path.exists(p):
            os.remove(p)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("recordings", help="a folder of *.rfrec recordings")
    ap.add_argument("--records", required=True,
                    help="a SQLite file (replaced for each cluster size) or a postgres:// URL")
    ap.add_argument("--out", required=True, help="the folder for the strips")
    ap.add_argument("--engine", choices=["dask", "ray"], default="dask")
    ap.add_argument("--workers", default="1,2", help="cluster sizes to run, e.g. 1,2")
    ap.add_argument("--line", default="default")
    args = ap.parse_args()
    recordings = sorted(glob.glob(os.path.join(os.path.abspath(args.recordings), "*.rfrec")))
    if not recordings:
        print(f"no *.rfrec recordings in {args.recordings}", file=sys.stderr)
        return 1
    run = run_dask if args.engine == "dask" else run_ray
    for workers in [int(w) for w in args.workers.split(",")]:
        out = os.path.abspath(os.path.join(args.out, f"{workers}-workers"))
        records = args.records
        if not records.startswith(("postgres://", "postgresql://")):
            records = os.path.abspath(f"{records}.{workers}-workers")
            fresh(records)
        fresh(out)
        results, took = run(recordings, workers, out, records, args.line)
        tiles = sum(t for _, t in results)
        print(f"{args.engine}, {workers} worker{'s' if workers > 1 else ''}: "
              f"{len(results)} rolls ({tiles} tiles) in {took:.2f} s, "
              f"{len(results) / took:.2f} rolls/s → {records}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
