"""The Python module's speed beside the command line's (docs/figures.md#the-python-module).

    PYTHONPATH=build/python python3 tests/bench/python_bench.py build/displace

Prints, each a median over repeats in one run:
- query: points a second for 1 M points on `water` (displace.query, the heights made in the call);
- heights: displace.heights against the milliseconds `displace sim` reports for the same synthesis;
- frames: Pipeline.frame wall time against the frame_ms of `displace sequence`'s CSV, same frames.
"""
import csv
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import displace


def median_seconds(call, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main():
    binary = sys.argv[1]
    scene = displace.Scene.builtin("water")
    points = np.random.default_rng(1).uniform(-500.0, 500.0, size=(1_000_000, 2))
    displace.query(scene, 1.0, points[:10])
    seconds = median_seconds(lambda: displace.query(scene, 1.0, points), 7)
    print(f"query: 1 M points in {seconds * 1e3:.1f} ms: {len(points) / seconds / 1e6:.2f} M points/s")

    with tempfile.TemporaryDirectory() as directory:
        exr = os.path.join(directory, "h.exr")
        cli = []
        for _ in range(7):
            out = subprocess.run([binary, "sim", "--scene", "water", "--time", "1", "--output", exr],
                                 check=True, capture_output=True, text=True).stdout
            cli.append(float(re.search(r"in ([0-9.]+) ms", out).group(1)))
        ours = median_seconds(lambda: displace.heights(scene, 1.0), 7) * 1e3
        theirs = statistics.median(cli)
        print(f"heights: water 256 x 256, module {ours:.2f} ms, displace sim {theirs:.2f} ms "
              f"(its synthesis, no EXR): ratio {ours / theirs:.3f}")

        size, first, count = "320x180", 10, 40
        pattern = os.path.join(directory, "f_####.png")
        subprocess.run([binary, "sequence", "--scene", "water", "--size", size, "--bake-work", "20000",
                        "--frames", f"0:{first + count - 1}", "--output", pattern], check=True, capture_output=True)
        with open(os.path.join(directory, "f.csv")) as file:
            rows = [row for row in csv.DictReader(file) if int(row["frame"]) >= first]
        theirs = statistics.median(float(row["frame_ms"]) for row in rows)
        scene["budget.bake_work"] = 20000
        pipe = displace.Pipeline(scene, size=(320, 180))
        for n in range(first):
            pipe.frame(n)
        walls = []
        for n in range(first, first + count):
            start = time.perf_counter()
            pipe.frame(n)
            walls.append((time.perf_counter() - start) * 1e3)
        ours = statistics.median(walls)
        print(f"frames: water 320 x 180, frames {first}..{first + count - 1}: Pipeline.frame {ours:.2f} ms "
              f"(wall, with the copy out), displace sequence {theirs:.2f} ms (frame_ms): ratio {ours / theirs:.3f}")


if __name__ == "__main__":
    main()
