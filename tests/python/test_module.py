"""The Python module (pipeline/python) against the command line, bit for bit, and its behaviour.

Run by ctest (entry `python`) with the build tree's python/ on PYTHONPATH and DISPLACE_BINARY naming
the `displace` program; the command's files are read with OpenImageIO's Python binding.
"""
import json
import os
import subprocess
import tempfile
import threading
import time
import unittest

import numpy as np
import OpenImageIO as oiio

import displace

BINARY = os.environ["DISPLACE_BINARY"]
SCENES = ["water", "calm", "bricks"]
MAP_SIZE = 64  # small maps: the comparisons are bit for bit, not about size


def small_scene(name):
    scene = displace.Scene.builtin(name)
    scene["source.map_size"] = MAP_SIZE
    return scene


def run(*args):
    return subprocess.run([BINARY, *args], check=True, capture_output=True, text=True).stdout


def read_image(path):
    image = oiio.ImageBuf(path)
    if image.has_error:
        raise RuntimeError(image.geterror())
    spec = image.spec()
    return spec, image


def channel(path, name):
    spec, image = read_image(path)
    index = spec.channelindex(name)
    if index < 0:
        raise KeyError(f"{path} has no channel {name}")
    return image.get_pixels(oiio.FLOAT)[:, :, index]


class AgainstTheCommandLine(unittest.TestCase):
    def setUp(self):
        self.directory = tempfile.TemporaryDirectory()
        self.dir = self.directory.name

    def tearDown(self):
        self.directory.cleanup()

    def scene_file(self, scene):
        path = os.path.join(self.dir, scene.name + ".toml")
        with open(path, "w") as file:
            file.write(scene.to_toml())
        return path

    def test_heights_are_what_sim_writes(self):
        for name in SCENES:
            with self.subTest(scene=name):
                scene = small_scene(name)
                scene["time.start"] = 1.5
                exr = os.path.join(self.dir, name + ".exr")
                run("sim", "--scene", self.scene_file(scene), "--output", exr)
                ours = displace.heights(scene)
                self.assertEqual(ours.dtype, np.float32)
                self.assertEqual(ours.shape, (MAP_SIZE, MAP_SIZE))
                np.testing.assert_array_equal(ours, channel(exr, "height"))
                # the same heights at the same time given explicitly
                np.testing.assert_array_equal(displace.heights(scene, 1.5), ours)

    def test_bake_is_what_bake_writes(self):
        cases = [("bilinear", "budgeted", 4), ("bilinear", "full", 8), ("center", "budgeted", 4), ("center", "exact", 1)]
        for name in SCENES:
            scene = small_scene(name)
            path = self.scene_file(scene)
            heights = displace.heights(scene, normalized=True)
            for cones, mode, sectors in cases:
                with self.subTest(scene=name, cones=cones, mode=mode, sectors=sectors):
                    exr = os.path.join(self.dir, f"{name}-{cones}-{mode}.exr")
                    line = run("bake", "--scene", path, "--cones", cones, "--mode", mode, "--sectors", str(sectors),
                               "--output", exr, "--stats")
                    theirs = json.loads(line)
                    ratios, apex, stats = displace.bake(heights, sectors=sectors, cones=cones, mode=mode)
                    self.assertEqual(ratios.shape, (MAP_SIZE, MAP_SIZE, sectors))
                    for s in range(sectors):
                        np.testing.assert_array_equal(ratios[:, :, s], channel(exr, f"cone{s}"))
                    np.testing.assert_array_equal(heights, channel(exr, "height"))
                    if cones == "bilinear":
                        np.testing.assert_array_equal(apex, channel(exr, "apex"))
                    else:
                        self.assertIsNone(apex)
                    self.assertEqual(list(stats.keys()), list(theirs.keys()))
                    for key in theirs:
                        if key != "bake_ms":
                            self.assertEqual(stats[key], theirs[key], key)

    def test_query_is_what_query_prints(self):
        rng = np.random.default_rng(7)
        for name in SCENES:
            with self.subTest(scene=name):
                scene = small_scene(name)
                points = rng.uniform(-300.0, 300.0, size=(50, 2))
                csv = os.path.join(self.dir, "points.csv")
                np.savetxt(csv, points, delimiter=",", fmt="%.17g")
                out = os.path.join(self.dir, "out.json")
                run("query", "--scene", self.scene_file(scene), "--points", csv, "--output", out, "--json")
                with open(out) as file:
                    theirs = json.load(file)["points"]
                ours = displace.query(scene, scene["time.start"], points)
                for n, row in enumerate(theirs):
                    self.assertEqual(ours["height_m"][n], np.float32(row["height_m"]))
                    self.assertEqual(ours["z"][n], np.float32(row["z"]))
                    np.testing.assert_array_equal(ours["normal"][n], np.float32(row["normal"]))
                    np.testing.assert_array_equal(ours["displacement"][n], np.float32(row["displacement_m"]))

    def test_frames_are_what_sequence_draws(self):
        for name in SCENES:
            with self.subTest(scene=name):
                scene = small_scene(name)
                pattern = os.path.join(self.dir, name + "_####.png")
                run("sequence", "--scene", self.scene_file(scene), "--size", "96x64", "--frames", "0:2",
                    "--output", pattern)
                pipeline = displace.Pipeline(scene, size=(96, 64))
                for n, frame in pipeline.frames(0, 3):
                    self.assertEqual(frame.shape, (64, 96, 4))
                    self.assertEqual(frame.dtype, np.uint8)
                    _, image = read_image(pattern.replace("####", f"{n:04d}"))
                    np.testing.assert_array_equal(frame, image.get_pixels(oiio.UINT8))
                if name != "water":
                    continue
                # the stats have bench-frame's keys, over the frames made
                report = os.path.join(self.dir, name + ".json")
                run("bench-frame", "--scene", self.scene_file(scene), "--size", "96x64", "--frames", "2",
                    "--json", report)
                with open(report) as file:
                    theirs = json.load(file)
                stats = pipeline.stats
                self.assertEqual(set(stats) - {"last"}, set(theirs))
                self.assertEqual(stats["stages"].keys(), theirs["stages"].keys())
                for stage in theirs["stages"]:
                    self.assertEqual(stats["stages"][stage].keys(), theirs["stages"][stage].keys())
                self.assertEqual(stats["frames_rendered"], 3)
                self.assertEqual(stats["last"]["frame"], 2)
                self.assertFalse(stats["last"]["cones_updated"])  # the sea changes everywhere: baked whole
                self.assertEqual(stats["effects"], theirs["effects"])


class BadInput(unittest.TestCase):
    def test_scene_keys(self):
        scene = displace.Scene.builtin("water")
        with self.assertRaisesRegex(KeyError, "unknown key"):
            scene["ocean.wind_sped"] = 3.0
        with self.assertRaises(ValueError):
            scene["ocean.wind_speed"] = -3.0
        with self.assertRaises(ValueError):
            scene["source.map_size"] = 1
        with self.assertRaises(TypeError):
            scene["ocean.wind_speed"] = object()
        with self.assertRaises(KeyError):
            scene["ocean.nothing"]
        with self.assertRaisesRegex(ValueError, "unknown scene"):
            displace.Scene.builtin("pond")
        with self.assertRaises(ValueError):
            displace.Scene.from_toml("[ocean\nwind_speed = 3")
        scene["ocean.wind_speed"] = 15.0
        self.assertEqual(scene["ocean.wind_speed"], 15.0)
        self.assertEqual(displace.Scene.from_toml(scene.to_toml())["ocean.wind_speed"], 15.0)

    def test_bake_input(self):
        good = np.zeros((8, 8), np.float32)
        with self.assertRaises(TypeError):
            displace.bake([["a", "b"], ["c", "d"]])
        with self.assertRaisesRegex(ValueError, "2-D"):
            displace.bake(np.zeros((8, 8, 2), np.float32))
        with self.assertRaisesRegex(ValueError, "NaN"):
            displace.bake(np.full((8, 8), np.nan, np.float32))
        with self.assertRaisesRegex(ValueError, r"\[0, 1\]"):
            displace.bake(np.full((8, 8), 3.0))
        with self.assertRaisesRegex(ValueError, "at least 2 x 2"):
            displace.bake(np.zeros((1, 1), np.float32))
        with self.assertRaisesRegex(ValueError, "at least 2 x 2"):
            displace.bake(np.zeros((0, 4), np.float32))
        with self.assertRaisesRegex(ValueError, "sectors"):
            displace.bake(good, sectors=3)
        with self.assertRaisesRegex(ValueError, "full baker"):
            displace.bake(good, cones="center", mode="full")
        with self.assertRaisesRegex(ValueError, "address"):
            displace.bake(good, address="mirror")
        # any layout or dtype numpy converts: the same cones as the float32 C-ordered copy
        rng = np.random.default_rng(3)
        heights = rng.uniform(0.0, 1.0, size=(12, 16))
        reference = displace.bake(heights.astype(np.float32))[0]
        np.testing.assert_array_equal(displace.bake(heights)[0], reference)  # float64
        fortran = np.asfortranarray(heights.astype(np.float32))
        np.testing.assert_array_equal(displace.bake(fortran)[0], reference)
        wide = np.zeros((12, 32), np.float32)
        wide[:, ::2] = heights
        np.testing.assert_array_equal(displace.bake(wide[:, ::2])[0], reference)  # not contiguous

    def test_query_and_pipeline_input(self):
        scene = displace.Scene.builtin("calm")
        with self.assertRaisesRegex(ValueError, r"\(N, 2\)"):
            displace.query(scene, 0.0, np.zeros((4, 3)))
        with self.assertRaisesRegex(ValueError, "finite"):
            displace.query(scene, 0.0, [[np.nan, 0.0]])
        with self.assertRaisesRegex(ValueError, "time"):
            displace.query(scene, np.inf, [[0.0, 0.0]])
        with self.assertRaises(TypeError):
            displace.query(scene, 0.0, "points")
        with self.assertRaisesRegex(ValueError, "backend"):
            displace.Pipeline(scene, backend="gpu")
        with self.assertRaises(ValueError):
            displace.Pipeline(scene, size=(0, 10))
        image_scene = displace.Scene.from_toml('[source]\nkind = "image"\npath = "heights.exr"\n')
        with self.assertRaisesRegex(ValueError, "height image"):
            displace.heights(image_scene)


def resident_kb():
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    raise RuntimeError("no VmRSS")


class Behaviour(unittest.TestCase):
    def test_heavy_calls_release_the_gil(self):
        # while one thread bakes, another runs Python and notes the time at every turn: with the GIL
        # held through the bake the notes would stop for the whole bake, released they keep coming
        heights = displace.heights(displace.Scene.builtin("calm"), normalized=True)
        # each call long enough to tell on a fast, quiet machine (about 0.25, 0.16 and 0.2 s on an
        # AMD EPYC, where a 256 storm's heights took 0.02-0.04 s and 200,000 points 0.056 s)
        storm = displace.Scene.builtin("storm")
        storm["source.map_size"] = 1024
        for call in (lambda: displace.bake(heights, mode="full"),
                     lambda: displace.heights(storm, 1.0),
                     lambda: displace.query(displace.Scene.builtin("storm"), 1.0, np.zeros((1500000, 2)))):
            span = []
            baking = threading.Event()

            def work():
                baking.set()
                start = time.perf_counter()
                call()
                span.extend([start, time.perf_counter()])

            worker = threading.Thread(target=work)
            notes = []
            worker.start()
            baking.wait()
            while worker.is_alive():
                notes.append(time.perf_counter())
            worker.join()
            start, end = span
            inside = [t for t in notes if start <= t <= end]
            gaps = np.diff([start] + inside + [end])
            self.assertGreater(end - start, 0.05, "the call is too short to tell")
            self.assertLess(gaps.max(), 0.25 * (end - start), "no Python ran for most of the call: the GIL was held")

    def test_a_thousand_frames_keep_resident_memory_flat(self):
        scene = small_scene("calm")
        scene["budget.bake_work"] = 500  # texels refined a frame: the cone path at a few ms a frame
        pipeline = displace.Pipeline(scene, size=(48, 32))
        for n in range(50):
            pipeline.frame(n)
        warm = resident_kb()
        for n in range(50, 1000):
            pipeline.frame(n)
        growth = resident_kb() - warm
        self.assertLess(growth, 4096, f"resident memory grew {growth} kB over 950 frames")


if __name__ == "__main__":
    unittest.main()
