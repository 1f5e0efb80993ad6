"""A boat on a sea, and a cone map for an engine, with the displace module and matplotlib.

1. A 12 m x 4 m boat's four hull points ride the built-in `storm` sea (or --scene): their heights and
   normals over a minute give its heave, pitch and roll (a rigid hull resting on four points, no
   dynamics), plotted to OUTPUT/boat.png.
2. A height image (--height-image, 8/16-bit grey PNG; by default the sea's heights at t = 0, written
   to OUTPUT/heights.png first) is baked into 4-sector bilinear cones and saved as an engine loads
   them: OUTPUT/cones.png (RGBA8, sqrt(ratio) rounded down) and OUTPUT/apex.png (8-bit, rounded up),
   both conservative for the 8-bit heights they were baked from.

    PYTHONPATH=build/python python3 demos/python/boat.py --output out/boat
"""
import argparse
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.image  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import displace  # noqa: E402

LENGTH_M, BEAM_M = 12.0, 4.0


def hull_points(centre):
    x, y = centre
    return np.array([[x + LENGTH_M / 2, y], [x - LENGTH_M / 2, y], [x, y + BEAM_M / 2], [x, y - BEAM_M / 2]])


def ride(scene, seconds, step):
    times = np.arange(0.0, seconds + 1e-9, step)
    points = hull_points((100.0, 100.0))  # bow, stern, port, starboard
    heave, pitch, roll, tilt = [], [], [], []
    for t in times:
        hit = displace.query(scene, float(t), points)
        h = hit["height_m"].astype(np.float64)
        heave.append(h.mean())
        pitch.append(math.degrees(math.atan2(h[0] - h[1], LENGTH_M)))
        roll.append(math.degrees(math.atan2(h[2] - h[3], BEAM_M)))
        # how far the water under the hull leans (the normals' largest angle from vertical)
        tilt.append(math.degrees(math.acos(float(hit["normal"][:, 2].min()))))
    return times, np.array(heave), np.array(pitch), np.array(roll), np.array(tilt)


def plot(path, scene_name, times, heave, pitch, roll, tilt):
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    top.plot(times, heave, color="tab:blue")
    top.set_ylabel("heave (m)")
    top.set_title(f"a {LENGTH_M:g} m x {BEAM_M:g} m boat on the '{scene_name}' sea (four hull points)")
    bottom.plot(times, pitch, label="pitch")
    bottom.plot(times, roll, label="roll")
    bottom.plot(times, tilt, label="steepest water under the hull", color="0.6", linewidth=0.8)
    bottom.set_ylabel("degrees")
    bottom.set_xlabel("time (s)")
    bottom.legend(loc="upper right", fontsize="small")
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


def bake_for_engine(image_path, output):
    image = matplotlib.image.imread(image_path)
    if image.ndim == 3:
        image = image[:, :, 0]
    heights = np.floor(np.asarray(image, np.float64) * 255.0 + 0.5) / 255.0  # the 8 bits the PNG holds
    cones, apex, stats = displace.bake(heights, sectors=4, cones="bilinear")
    # rounded the safe way: ratios down (a smaller cone claims less), apexes up
    ratio_bytes = np.clip(np.floor(np.sqrt(cones) * 255.0), 0, 255).astype(np.uint8)
    ratio_bytes -= ((ratio_bytes.astype(np.float64) / 255.0) ** 2 > cones).astype(np.uint8)
    apex_bytes = np.clip(np.ceil(apex.astype(np.float64) * 255.0), 0, 255).astype(np.uint8)
    matplotlib.image.imsave(os.path.join(output, "cones.png"), ratio_bytes)
    matplotlib.image.imsave(os.path.join(output, "apex.png"), apex_bytes, cmap="gray", vmin=0, vmax=255)
    return stats


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--output", required=True, help="directory for boat.png, heights.png, cones.png, apex.png")
    parser.add_argument("--scene", default="storm", help="a built-in scene or a scene file (default storm)")
    parser.add_argument("--seconds", type=float, default=60.0, help="how long the boat rides (default 60)")
    parser.add_argument("--height-image", help="a grey PNG to bake (default: the sea's heights at t = 0)")
    args = parser.parse_args()
    os.makedirs(args.output, exist_ok=True)
    scene = (displace.Scene.load(args.scene) if args.scene.endswith(".toml") else displace.Scene.builtin(args.scene))

    times, heave, pitch, roll, tilt = ride(scene, args.seconds, 0.25)
    plot(os.path.join(args.output, "boat.png"), scene.name, times, heave, pitch, roll, tilt)
    print(f"boat on '{scene.name}': heave {heave.min():+.2f} .. {heave.max():+.2f} m, "
          f"pitch up to {np.abs(pitch).max():.1f} deg, roll up to {np.abs(roll).max():.1f} deg "
          f"over {args.seconds:g} s -> {os.path.join(args.output, 'boat.png')}")

    image = args.height_image
    if image is None:
        image = os.path.join(args.output, "heights.png")
        unit = displace.heights(scene, 0.0, normalized=True)
        matplotlib.image.imsave(image, unit, cmap="gray", vmin=0.0, vmax=1.0)
    stats = bake_for_engine(image, args.output)
    print(f"cone map of '{image}': {stats['width']} x {stats['height']}, {stats['sectors']} sectors, "
          f"mean ratio {stats['mean_ratio']:.3f}, {stats['bake_ms']:.0f} ms -> cones.png, apex.png")


if __name__ == "__main__":
    main()
