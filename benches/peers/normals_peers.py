#!/usr/bin/env python3
"""Normal estimation and orientation for point clouds without normals: `zeroset normals` against
Open3D's `estimate_normals` + `orient_normals_consistent_tangent_plane`, on the same points, in
the same run; wall times, their ratios, and each side's normals against the files' own.

Run by hand, not by CI (see benches/peers/README.md), from the repository root:

    bash benches/peers/setup.sh --open3d        # once (Debian/Ubuntu: apt-get install libusb-1.0-0 first)
    cargo build --release -p zeroset-cli        # target/release/zeroset
    benches/peers/.venv/bin/python benches/peers/normals_peers.py                   # K = 16, 5 repeats
    benches/peers/.venv/bin/python benches/peers/normals_peers.py --neighbours 24 --clouds data/kitten.xyz
    benches/peers/.venv/bin/python benches/peers/normals_peers.py --open3d-only     # no zeroset binary

The clouds (`--clouds`, comma-separated; default data/bunny_points.ply, data/kitten.xyz,
samples/bunny_2k.xyzn; noisy ones come from noise_peers.py, e.g.
out/noise_peers/bunny_points_0.0025.xyzn) carry outward unit normals: they are the truth, and only their positions
are written, with 17 significant digits, to OUT/normals_peers/NAME.xyz, the file both sides read.

What is timed (warm-up of each configuration, then `--repeats` rounds alternating zeroset and
Open3D at each thread count; the upper median `sorted[R // 2]`, common.py's rule):
- zeroset: the whole process `zeroset normals NAME.xyz -o NAME_zeroset.ply --force --quiet
  --neighbours K`, wall clock from outside (start-up, reading the file, writing the binary PLY
  all counted), with RAYON_NUM_THREADS=1 and =N (`--mt-threads`, default: every CPU).
- Open3D: in a worker process (this script with `--open3d-worker`) that has already read
  NAME.xyz — reading excluded, which favours the peer — (a) `estimate_normals(
  KDTreeSearchParamKNN(K + 1))` on a fresh normal-less PointCloud and (b)
  `orient_normals_consistent_tangent_plane(K + 1)`, each timed and together (Open3D's KNN
  search counts the point itself; zeroset's K does not: both fit a plane to the point and its
  K nearest others, and link it to those K). Threads: the worker
  sets OMP_NUM_THREADS and its CPU affinity to T before importing open3d (Open3D 0.20's
  `estimate_normals` runs on TBB, which ignores OMP_NUM_THREADS but keeps to the affinity):
  T = 1 and T = N (N = Open3D's default, every CPU).
Ratios: Open3D total / zeroset process (> 1: zeroset faster), one thread each and each at its
fastest configuration.

Accuracy (from each configuration's last run; zeroset's PLY read back, Open3D's normals saved as
NAME_open3d_tT.xyzn): "flipped", the fraction of points whose normal points against the true one
(dot < 0); "inconsistent", min(flipped, 1 − flipped), since Open3D's orientation makes the
normals agree with each other but its global sign is arbitrary; the median, 90th and 99th
percentiles of the unsigned angle error acos(|dot|) in degrees. Tables are printed and written
to OUT/normals_peers/results.txt.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import common

# The worker's threads are fixed before open3d is imported (stray_peers imports it): OpenMP
# reads OMP_NUM_THREADS when it loads, and TBB keeps to the CPU affinity it finds.
WORKER_ENV = "NORMALS_PEERS_THREADS"
if "--open3d-worker" in sys.argv and WORKER_ENV in os.environ:
    _threads = int(os.environ[WORKER_ENV])
    os.environ["OMP_NUM_THREADS"] = str(_threads)
    os.sched_setaffinity(0, sorted(os.sched_getaffinity(0))[:_threads])

import numpy as np  # noqa: E402

from stray_peers import o3d, read_cloud  # noqa: E402  (exits cleanly without open3d)

REPO = common.REPO
DEFAULT_CLOUDS = "data/bunny_points.ply,data/kitten.xyz,samples/bunny_2k.xyzn"


def parse_args() -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--clouds", default=DEFAULT_CLOUDS, help="clouds with true normals, comma-separated")
    p.add_argument("--neighbours", type=int, default=16, metavar="K", help="K nearest neighbours, both sides")
    p.add_argument("--repeats", type=int, default=5, help="timed rounds after one warm-up")
    p.add_argument("--out", type=Path, default=REPO / "benches" / "peers" / "out")
    target = common.ORIGINAL_ENV.get("CARGO_TARGET_DIR")
    p.add_argument("--zeroset", type=Path, default=((REPO / target) if target else REPO / "target")
                   / "release" / "zeroset", help="the zeroset binary (default: the release build)")
    p.add_argument("--open3d-only", action="store_true", help="time Open3D alone (no zeroset binary needed)")
    common.add_mt_arg(p, "Open3D at N threads")
    p.add_argument("--open3d-worker", type=Path, metavar="XYZ", help=argparse.SUPPRESS)  # internal
    a = p.parse_args()
    if a.neighbours < 3 or a.repeats < 1:
        p.error("--neighbours must be at least 3 and --repeats at least 1")
    a.cloud_list = [Path(c) if Path(c).exists() else REPO / c for c in a.clouds.split(",") if c.strip()]
    a.threads = [1] + ([a.mt_threads] if a.mt_threads > 1 else [])
    return a


# ---------------------------------------------------------------------------------------------
# the Open3D worker: reads the points once, then answers "run" and "save PATH" lines on stdin


def open3d_worker(xyz: Path, k: int) -> None:
    points = o3d.utility.Vector3dVector(np.loadtxt(xyz, ndmin=2)[:, :3])
    pcd = None
    say = lambda obj: print("RESULT " + json.dumps(obj), flush=True)  # noqa: E731  (Open3D logs to stdout too)
    say({"cpus": len(os.sched_getaffinity(0)), "omp": os.environ.get("OMP_NUM_THREADS", "unset")})
    for line in sys.stdin:
        cmd = line.split(maxsplit=1)
        if cmd and cmd[0] == "run":
            pcd = o3d.geometry.PointCloud(points)  # fresh, without normals (else Open3D orients by them)
            t0 = time.perf_counter()
            pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(k))
            t1 = time.perf_counter()
            pcd.orient_normals_consistent_tangent_plane(k)
            t2 = time.perf_counter()
            say({"estimate": t1 - t0, "orient": t2 - t1, "total": t2 - t0})
        elif cmd and cmd[0] == "save":
            np.savetxt(cmd[1].strip(), np.hstack([np.asarray(pcd.points), np.asarray(pcd.normals)]), fmt="%.17g")
            say({"saved": cmd[1].strip()})


class Worker:
    """The parent's handle on one worker process at `threads` threads."""

    def __init__(self, xyz: Path, k: int, threads: int):
        env = {**common.ORIGINAL_ENV, WORKER_ENV: str(threads)}
        # Open3D's KNN search counts the point itself: K + 1 gives both sides the point and its
        # K nearest others, in the plane and in the orientation graph.
        cmd = [sys.executable, str(Path(__file__).resolve()), "--open3d-worker", str(xyz), "--neighbours", str(k + 1)]
        self.proc = subprocess.Popen(cmd, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.info = self._answer()

    def _answer(self) -> dict:
        for line in self.proc.stdout:
            if line.startswith("RESULT "):
                return json.loads(line[len("RESULT "):])
        sys.exit(f"the Open3D worker ended early (exit status {self.proc.wait()})")

    def ask(self, command: str) -> dict:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self._answer()

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


# ---------------------------------------------------------------------------------------------
# zeroset


def check_zeroset(binary: Path) -> None:
    """Exits with a clear message unless `binary` exists and has a `normals` command."""
    hint = "(or --zeroset PATH; --open3d-only times Open3D alone)"
    if not binary.is_file():
        sys.exit(f"{binary} is missing: cargo build --release -p zeroset-cli {hint}")
    if subprocess.run([str(binary), "normals", "--help"], capture_output=True).returncode != 0:
        sys.exit(f"{binary} has no `normals` command (an older build?): rebuild it {hint}")


def zeroset_run(binary: Path, xyz: Path, ply: Path, k: int, threads: int) -> float:
    """Seconds of the whole `zeroset normals` process."""
    cmd = [str(binary), "normals", str(xyz), "-o", str(ply), "--force", "--quiet", "--neighbours", str(k)]
    env = {**common.ORIGINAL_ENV, "RAYON_NUM_THREADS": str(threads)}
    t = time.perf_counter()
    run = subprocess.run(cmd, env=env, capture_output=True, text=True)
    seconds = time.perf_counter() - t
    if run.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed (exit status {run.returncode}):\n{run.stderr}")
    return seconds


def read_zeroset_ply(path: Path) -> np.ndarray:
    """(n, 6) x y z nx ny nz from zeroset's binary little-endian PLY of doubles."""
    data = path.read_bytes()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii").split()
    props = [header[i + 2] for i, w in enumerate(header) if w == "property"]
    if "binary_little_endian" not in header or props != ["x", "y", "z", "nx", "ny", "nz"] or \
            any(header[i + 1] != "double" for i, w in enumerate(header) if w == "property"):
        sys.exit(f"{path}: expected binary_little_endian doubles x y z nx ny nz, got {' '.join(header)}")
    n = int(header[header.index("vertex") + 1])
    return np.frombuffer(data, dtype="<f8", count=6 * n, offset=end).reshape(n, 6)


# ---------------------------------------------------------------------------------------------
# accuracy and the table


def accuracy(points: np.ndarray, est: np.ndarray, truth_points: np.ndarray, truth: np.ndarray) -> dict:
    if est.shape != truth.shape or np.abs(points - truth_points).max() > 1e-9 * np.abs(truth_points).max():
        sys.exit("a side's output does not have the input's points in the input's order")
    dot = np.sum(est * truth, axis=1) / np.linalg.norm(est, axis=1)  # truth is unit length
    flipped = float(np.mean(dot < 0))
    angle = np.degrees(np.arccos(np.clip(np.abs(dot), 0.0, 1.0)))
    return {"flipped": flipped, "inconsistent": min(flipped, 1 - flipped),
            "p50": float(np.median(angle)), "p90": float(np.quantile(angle, 0.9)),
            "p99": float(np.quantile(angle, 0.99))}


def median(times: list[float]) -> float:
    return sorted(times)[len(times) // 2] * 1e3  # ms, the upper median


def acc_cells(a: dict) -> list[str]:
    return [f"{a['flipped']:.4f}", f"{a['inconsistent']:.4f}", f"{a['p50']:.2f}", f"{a['p90']:.2f}",
            f"{a['p99']:.2f}"]


def cloud_report(args, name: str, n: int, zs: dict, o3: dict, infos: dict) -> str:
    header = ["side", "threads", "estimate ms", "orient ms", "total ms", "flipped", "inconsistent",
              "angle° p50", "p90", "p99"]
    body = []
    for t, r in zs.items():
        body.append(["zeroset normals (whole process)", f"RAYON {t}", "—", "—", common.fmt_ms(median(r["total"])),
                     *acc_cells(r["acc"])])
    for t, r in o3.items():
        i = infos[t]
        body.append(["Open3D (the calls alone)", f"OMP {i['omp']}, {i['cpus']} CPU",
                     *(common.fmt_ms(median(r[key])) for key in ("estimate", "orient", "total")), *acc_cells(r["acc"])])
    lines = [f"=== {name}: {n} points, K = {args.neighbours}; upper median of {args.repeats} after a warm-up ===",
             common.render_text(header, body, left=2)]
    if zs:
        one = common.ratio(median(o3[1]["total"]), median(zs[1]["total"]))
        (bo, o_ms), (bz, z_ms) = (common.fastest({t: median(r["total"]) for t, r in side.items()}) for side in (o3, zs))
        lines.append(f"Open3D / zeroset (total; > 1: zeroset faster): one thread each {common.fmt_ratio(one)}; "
                     f"each at its fastest (Open3D at {bo} thread(s) / zeroset at {bz}) "
                     f"{common.fmt_ratio(common.ratio(o_ms, z_ms))}")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------


def main() -> None:
    args = parse_args()
    if args.open3d_worker is not None:
        return open3d_worker(args.open3d_worker, args.neighbours)
    if not args.open3d_only:
        check_zeroset(args.zeroset)
    out = args.out / "normals_peers"
    out.mkdir(parents=True, exist_ok=True)
    header = [f"normals_peers: K = {args.neighbours}, {args.repeats} repeats; python {sys.version.split()[0]}, "
              f"numpy {np.__version__}, open3d {o3d.__version__}",
              f"threads: zeroset RAYON_NUM_THREADS = {', '.join(map(str, args.threads))}"
              + (" (skipped: --open3d-only)" if args.open3d_only else "")
              + f"; Open3D OMP_NUM_THREADS and CPU affinity = {', '.join(map(str, args.threads))}"
              f" (of {common.cpu_count()} CPUs)",
              "zeroset: whole process, wall clock from outside; Open3D: the two calls alone, in-process "
              "(reading the file excluded, which favours the peer)"]
    print("\n".join(header), flush=True)
    reports = []
    for cloud in args.cloud_list:
        name = cloud.stem
        truth_p, truth_n = read_cloud(cloud)
        xyz = out / f"{name}.xyz"
        np.savetxt(xyz, truth_p, fmt="%.17g")
        truth_p = np.loadtxt(xyz, ndmin=2)  # the coordinates as both sides read them
        ply = out / f"{name}_zeroset.ply"
        workers = {t: Worker(xyz, args.neighbours, t) for t in args.threads}
        zs = {} if args.open3d_only else {t: {"total": []} for t in args.threads}
        o3 = {t: {"estimate": [], "orient": [], "total": []} for t in args.threads}
        # One warm-up round (discarded), then alternate zeroset and Open3D at each thread count.
        for round_ in range(args.repeats + 1):
            for t in args.threads:
                if zs:
                    s = zeroset_run(args.zeroset, xyz, ply, args.neighbours, t)
                    if round_:
                        zs[t]["total"].append(s)
                    if round_ == args.repeats:  # the last run's normals
                        a = read_zeroset_ply(ply)
                        zs[t]["acc"] = accuracy(a[:, :3], a[:, 3:], truth_p, truth_n)
                r = workers[t].ask("run")
                if round_:
                    for key in o3[t]:
                        o3[t][key].append(r[key])
        for t, w in workers.items():
            saved = out / f"{name}_open3d_t{t}.xyzn"
            w.ask(f"save {saved}")
            w.close()
            a = np.loadtxt(saved, ndmin=2)
            o3[t]["acc"] = accuracy(a[:, :3], a[:, 3:], truth_p, truth_n)
        reports.append(cloud_report(args, name, len(truth_p), zs, o3, {t: w.info for t, w in workers.items()}))
        print("\n" + reports[-1], flush=True)
    facts = common.machine_facts([("load", common.loadavg())], [("open3d", o3d.__version__)])
    text = "\n\n".join(["\n".join(header), *reports, "\n".join(f"{k}: {v}" for k, v in facts)]) + "\n"
    (out / "results.txt").write_text(text)
    print("\n" + "\n".join(f"{k}: {v}" for k, v in facts))
    print(f"\nwrote {out / 'results.txt'}")


if __name__ == "__main__":
    main()
