#!/usr/bin/env python3
"""The figures and README.md of `displace report`, from the CSV and JSON it wrote.

    python3 demos/report/plot_report.py DIR

Reads DIR/report.json, cost.csv, grazing.csv, bake.csv, frame.csv, heatmaps.csv and the
heatmap_*.png data images; writes DIR/*.png figures and DIR/README.md. Every number in the README's
tables is computed here from those CSVs (tests/report_check.py recomputes them on its own).
"""
import csv
import io
import json
import math
import os
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

RMSE_FLOOR = 0.01  # rmse below this is drawn at it (log axes)
FETCH_FLOOR = 0.5  # bump reads no height: drawn at half a fetch
GRAZING_FETCH_BUDGET = 64  # fetches per pixel of the grazing figure's left panel
DECISION_TARGETS = (1.0, 3.0, 10.0)  # rmse targets of the "which method" tables
HORIZON_BAND_DEG = 2.0  # the horizon band: the grazing elevations at or below this, in degrees
HORIZON_BASE_DEG = 45.0  # what the band is compared with: the default camera's elevation
FRACTION_FLOOR = 1e-4  # a fraction of pixels off below this is drawn at it (log axes)
SURFACE_METHODS = {"bump", "parallax", "parallax-limited", "parallax-slope"}


def write_whole(path, data):
    """Writes the bytes whole or not at all, as the project's C++ writer does (render/files.h): a
    temporary in the same directory, fsync, rename, fsync of the directory; removed on failure."""
    directory = os.path.dirname(os.path.abspath(path))
    temporary = os.path.join(directory, f".{os.path.basename(path)}.partial-{os.getpid()}")
    try:
        with open(temporary, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temporary, path)
    except BaseException:
        if os.path.exists(temporary):
            os.unlink(temporary)
        raise
    descriptor = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)


def save_figure(fig, path):
    """A figure as PNG bytes in memory, then written whole (write_whole)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    write_whole(path, buffer.getvalue())


def read_table(directory, name):
    with open(os.path.join(directory, name), newline="") as handle:
        return list(csv.DictReader(handle))


def number(text):
    return math.inf if text == "inf" else float(text)


def fmt_ms(value):
    return f"{value:.1f}" if value >= 1 else f"{value:.2f}"


def fmt_budget(value):
    return "unlimited" if math.isinf(value) else f"{value:g}"


def method_order(rows):
    seen = []
    for row in rows:
        if row["method"] not in seen:
            seen.append(row["method"])
    return seen


def style(methods):
    colours = plt.get_cmap("tab20").colors
    markers = "os^vD<>pPhX*dH8"
    return {m: (colours[i % len(colours)], markers[i % len(markers)]) for i, m in enumerate(methods)}


def pareto(points):
    """The points no other point beats in both coordinates (lower is better), by x."""
    front, best = [], math.inf
    for x, y, label in sorted(points, key=lambda p: (p[0], p[1])):
        if y < best:
            front.append((x, y, label))
            best = y
    return front


# ---- the tables (tests/report_check.py recomputes each one)

def fewest_fetches(rows, target):
    """Per method: the run with the fewest mean fetches reaching rmse <= target (None if none)."""
    best = {}
    for row in rows:
        if float(row["rmse"]) > target:
            continue
        method = row["method"]
        if method not in best or float(row["mean_fetches"]) < float(best[method]["mean_fetches"]):
            best[method] = row
    return best


def steps_needed(rows, target):
    """{(method, elevation): fewest steps reaching rmse <= target, or None} over grazing rows."""
    needed = {}
    for row in rows:
        key = (row["method"], float(row["elevation_deg"]))
        needed.setdefault(key, None)
        if float(row["rmse"]) <= target:
            steps = int(row["steps"])
            if needed[key] is None or steps < needed[key]:
                needed[key] = steps
    return needed


def cheapest(rows, target):
    """The row with the fewest mean fetches reaching rmse <= target (ties: lower rmse), or None."""
    within = [r for r in rows if float(r["rmse"]) <= target]
    return min(within, key=lambda r: (float(r["mean_fetches"]), float(r["rmse"]))) if within else None


def horizon_rows(rows, steps):
    """{(scene, method, elevation): row} at `steps`, or the one row of a method with no steps to give."""
    chosen = {}
    for row in rows:
        key = (row["scene"], row["method"], float(row["elevation_deg"]))
        if row["method"] in SURFACE_METHODS or int(row["steps"]) == steps:
            chosen[key] = row
    return chosen


def horizon_band(rows, scene, steps):
    """Per method of `scene`: the band's mean fetches, rmse and fraction off (means over the elevations
    <= HORIZON_BAND_DEG) next to the same at HORIZON_BASE_DEG, and the fetch ratio (None if 45 has none)."""
    chosen = horizon_rows([r for r in rows if r["scene"] == scene], steps)
    band = {}
    for method in method_order([r for r in rows if r["scene"] == scene]):
        low = [r for (s, m, e), r in chosen.items() if m == method and e <= HORIZON_BAND_DEG]
        base = chosen.get((scene, method, HORIZON_BASE_DEG))
        if not low or base is None:
            continue
        mean = lambda name: statistics.fmean(float(r[name]) for r in low)  # noqa: E731
        entry = {"fetches": mean("mean_fetches"), "rmse": mean("rmse"), "over": mean("fraction_over_10"),
                 "base_fetches": float(base["mean_fetches"]), "base_rmse": float(base["rmse"]),
                 "base_over": float(base["fraction_over_10"])}
        entry["ratio"] = entry["fetches"] / entry["base_fetches"] if entry["base_fetches"] > 0 else None
        band[method] = entry
    return band


def frame_summary(rows):
    """Per frame budget: medians of the stages, p95 of the frame, error and ratio statistics."""
    budgets = []
    for row in rows:
        if row["frame_budget_ms"] not in budgets:
            budgets.append(row["frame_budget_ms"])
    summary = []
    for budget in budgets:
        mine = [r for r in rows if r["frame_budget_ms"] == budget]
        column = lambda name: [float(r[name]) for r in mine]  # noqa: E731
        frames = sorted(column("frame_ms"))
        summary.append({
            "budget": number(budget),
            "sim": statistics.median(column("sim_ms")),
            "bake": statistics.median(column("bake_ms")),
            "upload": statistics.median(column("upload_ms")),
            "render": statistics.median(column("render_ms")),
            "frame": statistics.median(frames),
            "frame_p95": frames[min(len(frames) - 1, int(math.ceil(0.95 * len(frames))) - 1)],
            "rmse_median": statistics.median(column("rmse")),
            "rmse_max": max(column("rmse")),
            "ratio": statistics.median(column("mean_ratio")),
            "fetches": statistics.median(column("mean_fetches")),
            "frames": len(mine),
        })
    return summary


# ---- the figures

def cost_figure(directory, scene, rows, target, styles):
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for axis, column, label in ((axes[0], "mean_fetches", "mean fetches per pixel (hit pixels)"),
                                (axes[1], "median_ms", "device milliseconds (median)")):
        points = []
        for method in method_order(rows):
            mine = [r for r in rows if r["method"] == method]
            xs = [max(float(r[column]), FETCH_FLOOR if column == "mean_fetches" else 1e-3) for r in mine]
            ys = [max(float(r["rmse"]), RMSE_FLOOR) for r in mine]
            colour, marker = styles[method]
            axis.plot(xs, ys, marker=marker, color=colour, label=method, linewidth=1.2, markersize=5)
            points += [(x, y, method) for x, y in zip(xs, ys)]
        front = pareto(points)
        axis.step([p[0] for p in front], [p[1] for p in front], where="post", color="black", linestyle="--",
                  linewidth=1, label="Pareto front")
        axis.scatter([p[0] for p in front], [p[1] for p in front], s=70, facecolors="none", edgecolors="black",
                     zorder=5)
        axis.axhline(target, color="grey", linewidth=0.8, linestyle=":")
        axis.set_xscale("log")
        axis.set_yscale("log")
        axis.set_xlabel(label)
        axis.grid(True, which="major", alpha=0.3)
    axes[0].set_ylabel("rmse against the reference (8-bit units)")
    axes[1].legend(fontsize=7, ncol=2, loc="upper right")
    fig.suptitle(f"{scene}: error against what it costs (dotted: rmse = {target:g})")
    fig.tight_layout()
    name = f"cost_{scene}.png"
    save_figure(fig, os.path.join(directory, name))
    plt.close(fig)
    return name


def grazing_figure(directory, rows, scenes, target, styles):
    scenes = [s for s in scenes if any(r["scene"] == s for r in rows)]
    fig, axes = plt.subplots(1, len(scenes), figsize=(5.2 * len(scenes) + 1.8, 4.8), squeeze=False, sharey=True)
    for axis, scene in zip(axes[0], scenes):
        mine = [r for r in rows if r["scene"] == scene]
        for method in method_order(mine):
            elevations, errors = [], []
            for elevation in sorted({float(r["elevation_deg"]) for r in mine}):
                runs = [r for r in mine if r["method"] == method and float(r["elevation_deg"]) == elevation
                        and float(r["mean_fetches"]) <= GRAZING_FETCH_BUDGET]
                if runs:
                    elevations.append(elevation)
                    errors.append(max(min(float(r["rmse"]) for r in runs), RMSE_FLOOR))
            colour, marker = styles[method]
            axis.plot(elevations, errors, marker=marker, color=colour, label=method, linewidth=1.2, markersize=5)
        axis.axhline(target, color="grey", linewidth=0.8, linestyle=":")
        axis.set_xscale("log")
        axis.set_yscale("log")
        ticks = sorted({float(r["elevation_deg"]) for r in mine})
        axis.set_xticks(ticks)
        axis.set_xticklabels([f"{e:g}" for e in ticks], fontsize=7)
        axis.minorticks_off()
        axis.set_xlabel("view elevation above the plane (degrees)")
        axis.set_title(scene)
        axis.grid(True, alpha=0.3)
    axes[0][0].set_ylabel(f"best rmse within {GRAZING_FETCH_BUDGET} fetches per pixel")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="center right")
    fig.tight_layout(rect=(0, 0, 0.87, 1))
    save_figure(fig, os.path.join(directory, "grazing.png"))
    plt.close(fig)
    return "grazing.png"


def horizon_figure(directory, rows, scenes, steps, styles):
    scenes = [s for s in scenes if any(r["scene"] == s for r in rows)]
    chosen = horizon_rows(rows, steps)
    panels = (("mean_fetches", "mean fetches per pixel (hit pixels)", FETCH_FLOOR),
              ("rmse", "rmse against the reference (8-bit units)", RMSE_FLOOR),
              ("fraction_over_10", "fraction of pixels off by more than 10", FRACTION_FLOOR))
    fig, axes = plt.subplots(len(panels), len(scenes), figsize=(4.6 * len(scenes) + 1.8, 3.3 * len(panels)),
                             squeeze=False, sharex=True)
    elevations = sorted({float(r["elevation_deg"]) for r in rows})
    for column, scene in enumerate(scenes):
        methods = method_order([r for r in rows if r["scene"] == scene])
        for line, (name, label, floor) in enumerate(panels):
            axis = axes[line][column]
            for method in methods:
                points = [(e, chosen[(scene, method, e)]) for e in elevations if (scene, method, e) in chosen]
                colour, marker = styles[method]
                axis.plot([e for e, _ in points], [max(float(r[name]), floor) for _, r in points], marker=marker,
                          color=colour, label=method, linewidth=1.2, markersize=4)
            axis.axvspan(min(elevations), HORIZON_BAND_DEG, color="grey", alpha=0.12)
            axis.set_xscale("log")
            axis.set_yscale("log")
            axis.set_xticks(elevations)
            axis.set_xticklabels([f"{e:g}" for e in elevations], fontsize=7)
            axis.minorticks_off()
            axis.grid(True, alpha=0.3)
            if column == 0:
                axis.set_ylabel(label, fontsize=8)
            if line == 0:
                axis.set_title(scene)
            if line == len(panels) - 1:
                axis.set_xlabel("view elevation above the plane (degrees)")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc="center right")
    fig.suptitle(f"The horizon band (shaded: at or below {HORIZON_BAND_DEG:g} degrees) at {steps} steps")
    fig.tight_layout(rect=(0, 0, 0.88, 1))
    save_figure(fig, os.path.join(directory, "horizon.png"))
    plt.close(fig)
    return "horizon.png"


def bake_figure(directory, rows):
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 4.8))
    for kind, colour in (("center", "tab:blue"), ("bilinear", "tab:orange")):
        for series, marker, line in (("budget", "o", "-"), ("tolerance", "s", ":")):
            if series == "budget":
                mine = [r for r in rows if r["cones"] == kind and float(r["tolerance"]) == 0.25]
            else:
                mine = [r for r in rows if r["cones"] == kind and r["budget_ms"] == "inf"]
            mine.sort(key=lambda r: float(r["bake_ms"]))
            axes[0].plot([float(r["bake_ms"]) for r in mine], [float(r["mean_ratio"]) for r in mine], marker=marker,
                         linestyle=line, color=colour, label=f"{kind} cones, by {series}")
            if kind == "bilinear":
                reached = [r for r in mine if r["acm4_fetches"]]
                axes[1].plot([float(r["bake_ms"]) for r in reached], [float(r["acm4_fetches"]) for r in reached],
                             marker=marker, linestyle=line, color=colour, label=f"bilinear, by {series}")
    for row in rows:
        if row["cones"] == "bilinear-full":
            axes[0].scatter([float(row["bake_ms"])], [float(row["mean_ratio"])], marker="*", s=160, color="black",
                            label="bake_bilinear_cones (full bake)", zorder=5)
            if row["acm4_fetches"]:
                axes[1].scatter([float(row["bake_ms"])], [float(row["acm4_fetches"])], marker="*", s=160,
                                color="black", label="bake_bilinear_cones (full bake)", zorder=5)
    axes[0].set_xscale("log")
    axes[0].set_xlabel("bake milliseconds (4 sectors)")
    axes[0].set_ylabel("mean cone ratio (higher: tighter, fewer steps)")
    axes[0].legend(fontsize=8)
    axes[0].grid(True, alpha=0.3)
    axes[1].set_xscale("log")
    axes[1].set_xlabel("bake milliseconds (bilinear, 4 sectors)")
    axes[1].set_ylabel("acm4 fetches per pixel at the fewest steps reaching the target")
    axes[1].legend(fontsize=8)
    axes[1].grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, os.path.join(directory, "bake.png"))
    plt.close(fig)
    return "bake.png"


def frame_figure(directory, rows, summary):
    fig, axes = plt.subplots(1, 2, figsize=(12.5, 4.8))
    for entry in summary:
        key = "inf" if math.isinf(entry["budget"]) else None
        mine = [r for r in rows if (r["frame_budget_ms"] == key if key else
                                    (r["frame_budget_ms"] != "inf" and float(r["frame_budget_ms"]) == entry["budget"]))]
        axes[0].plot([int(r["frame"]) for r in mine], [max(float(r["rmse"]), RMSE_FLOOR / 10) for r in mine],
                     label=(f"frame budget {fmt_budget(entry['budget'])} ms" if math.isfinite(entry["budget"]) else "no frame budget"), linewidth=1)
    axes[0].set_yscale("log")
    axes[0].set_xlabel("frame")
    axes[0].set_ylabel("rmse against the reference (8-bit units)")
    axes[0].legend(fontsize=8)
    axes[0].grid(True, alpha=0.3)
    labels = [fmt_budget(e["budget"]) for e in summary]
    bottom = np.zeros(len(summary))
    for stage, colour in (("sim", "tab:blue"), ("bake", "tab:orange"), ("upload", "tab:green"), ("render", "tab:red")):
        values = np.array([e[stage] for e in summary])
        axes[1].bar(labels, values, bottom=bottom, color=colour, label=stage)
        bottom += values
    axes[1].set_xlabel("frame budget (ms)")
    axes[1].set_ylabel("median milliseconds per frame")
    axes[1].legend(fontsize=8)
    axes[1].grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    save_figure(fig, os.path.join(directory, "frame.png"))
    plt.close(fig)
    return "frame.png"


def heatmap_figure(directory, rows):
    images = [np.array(Image.open(os.path.join(directory, r["file"])), dtype=np.float64) for r in rows]
    top = max(float(np.max(image)) for image in images)
    columns = min(5, len(rows))
    lines = (len(rows) + columns - 1) // columns
    fig, axes = plt.subplots(lines, columns, figsize=(2.6 * columns + 1.2, 2.8 * lines), squeeze=False,
                             layout="constrained")
    colormap = plt.get_cmap("turbo").copy()
    colormap.set_bad("black")
    shown = None
    for axis, row, image in zip(axes.flat, rows, images):
        iterations = np.ma.masked_where(image == 0, image - 1)  # 0 in the file: off the relief
        shown = axis.imshow(iterations, cmap=colormap, vmin=0, vmax=max(top - 1, 1), interpolation="nearest")
        axis.set_title(f"{row['method']}: {float(row['mean_iterations']):.1f} mean", fontsize=9)
        axis.axis("off")
    for axis in list(axes.flat)[len(rows):]:
        axis.axis("off")
    fig.colorbar(shown, ax=axes, shrink=0.9, label="search iterations per pixel")
    save_figure(fig, os.path.join(directory, "heatmaps.png"))
    plt.close(fig)
    return "heatmaps.png"


# ---- the README

def table(name, header, rows):
    lines = [f"<!-- table:{name} -->", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(cell) for cell in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def main():
    directory = sys.argv[1]
    info = json.load(open(os.path.join(directory, "report.json")))
    target = float(info["target_rmse"])
    cost = read_table(directory, "cost.csv")
    grazing = read_table(directory, "grazing.csv")
    bake = read_table(directory, "bake.csv")
    frame = read_table(directory, "frame.csv")
    heatmaps = read_table(directory, "heatmaps.csv")
    styles = style(method_order(cost + grazing))
    scenes = info["scenes"]

    out = []
    out.append("# What accuracy costs in time\n")
    out.append(
        f"Generated by `{info['command']}` on {info['date']}: {info['device']} ({info['device_type']}), "
        f"{info['cpu_threads']} CPU threads, {info['image_side']} x {info['image_side']} pixels, "
        f"{info['refine']} refinement steps, {info['repeat']} render(s) per point, in {info['seconds']['total']:g} s "
        f"(cost {info['seconds']['cost']:g} s, grazing {info['seconds']['grazing']:g} s, bake "
        f"{info['seconds']['bake']:g} s, frame {info['seconds']['frame']:g} s, heatmaps "
        f"{info['seconds']['heatmaps']:g} s). Error is the rmse of the picture against the exact reference of the "
        f"same heights and view, in 8-bit units over the pixels where either hit the relief; the target is "
        f"rmse <= {target:g}. Fetches are height and cone reads per hit pixel, read back from the device. The CSV "
        f"and JSON next to this file hold every number; the device times are lavapipe's when the device is the "
        f"CPU, so compare them with each other, not with a GPU.\n")

    # summary: which method and how many steps
    out.append("## Which method, how many steps\n")
    out.append(f"For each scene seen from the default camera (about 45 degrees), the methods that reach rmse <= "
               f"{target:g}, ordered by the fetches they need (fewest first); `-` where a method does not reach it "
               f"at {max(info['steps'])} steps.\n")
    for scene in scenes:
        rows = [r for r in cost if r["scene"] == scene]
        best = fewest_fetches(rows, target)
        reached = sorted(best.items(), key=lambda item: float(item[1]["mean_fetches"]))
        missing = [m for m in method_order(rows) if m not in best]
        body = [[m, r["steps"], f"{float(r['mean_fetches']):.1f}", fmt_ms(float(r["median_ms"])),
                 f"{float(r['rmse']):.2f}"] for m, r in reached]
        body += [[m, "-", "-", "-", "-"] for m in missing]
        out.append(f"**{scene}**\n")
        out.append(table(f"best:{scene}", ["method", "steps", "fetches/pixel", "device ms", "rmse"], body))

    out.append("**At your viewing angle and error target**: from the grazing runs (section 2), the method and "
               "step count with the fewest fetches per pixel that reach each rmse target at each elevation "
               "(`-`: no method does within the steps tried).\n")
    for scene in scenes:
        rows = [r for r in grazing if r["scene"] == scene]
        if not rows:
            continue
        body = []
        for elevation in sorted({float(r["elevation_deg"]) for r in rows}):
            at = [r for r in rows if float(r["elevation_deg"]) == elevation]
            for goal in DECISION_TARGETS:
                best = cheapest(at, goal)
                body.append([f"{elevation:g}", f"{goal:g}"] + (
                    [best["method"], best["steps"], f"{float(best['mean_fetches']):.1f}",
                     fmt_ms(float(best["median_ms"]))] if best else ["-", "-", "-", "-"]))
        out.append(f"**{scene}**\n")
        out.append(table(f"decide:{scene}", ["elevation deg", "rmse target", "method", "steps", "fetches/pixel",
                                             "device ms"], body))

    # 1 cost
    out.append("## 1. Render cost against error\n")
    out.append(
        "One line per method: rmse against mean fetches per pixel (left) and device milliseconds (right) as the "
        f"step count grows ({', '.join(str(s) for s in info['steps'])}); log axes, rmse below {RMSE_FLOOR} drawn at "
        f"{RMSE_FLOOR}. The dashed black steps are the Pareto front: the runs no other run beats in both cost and "
        "error, so a method off the front is never the right choice at that cost. Bump and the parallax family take "
        "no steps and show as one point; the searching methods fall until their search resolves the surface and then "
        "flatten where what is left is refinement or the method's own bias.\n")
    for scene in scenes:
        name = cost_figure(directory, scene, [r for r in cost if r["scene"] == scene], target, styles)
        out.append(f"![cost, {scene}]({name})\n")

    # 2 grazing
    out.append("## 2. Grazing angles\n")
    name = grazing_figure(directory, grazing, scenes, target, styles)
    out.append(
        f"Each plane scene seen from {', '.join(f'{e:g}' for e in info['elevations'])} degrees above the patch "
        f"(the eye 1.2 patch widths from its centre, the field of view narrowed until the patch fills the image, and "
        f"in the low views a wrapped map tiled: the horizon band below). The figure gives, per method, the lowest rmse it reaches within "
        f"{GRAZING_FETCH_BUDGET} mean fetches per pixel at each elevation; the tables give the fewest steps "
        f"(of {', '.join(str(s) for s in info['grazing_steps'])}) that reach rmse <= {target:g} (`-`: none does). "
        "Low views are where fixed-step searches skip thin features and cones with loose ratios crawl.\n")
    out.append(f"![grazing]({name})\n")
    needed = None
    for scene in scenes:
        rows = [r for r in grazing if r["scene"] == scene]
        if not rows:
            continue
        needed = steps_needed(rows, target)
        elevations = sorted({float(r["elevation_deg"]) for r in rows})
        body = []
        for method in method_order(rows):
            body.append([method] + ["-" if needed[(method, e)] is None else needed[(method, e)] for e in elevations])
        out.append(f"**{scene}**: steps for rmse <= {target:g} at each elevation\n")
        out.append(table(f"grazing:{scene}", ["method"] + [f"{e:g} deg" for e in elevations], body))

    # 2b horizon band
    steps = int(info["horizon_steps"])
    name = horizon_figure(directory, grazing, scenes, steps, styles)
    elevations = sorted({float(r["elevation_deg"]) for r in grazing})
    band_elevations = ", ".join(f"{e:g}" for e in elevations if e <= HORIZON_BAND_DEG)
    out.append("### The horizon band\n")
    out.append(
        f"Near the horizon the rays are nearly parallel to the plane. The grazing views above go down to "
        f"{min(elevations):g} degrees: there a wrapped map is tiled (up to {info['max_grazing_tile']} copies a side, "
        "scaled so its slopes stay) until a ray entering the near edge can cross the relief's slab on the patch, and "
        "the field of view narrows until the patch fills the image; `tile`, `fov_y_deg` and `reference_pixels` in "
        f"grazing.csv say what each view saw. The figure gives each method at {steps} steps (the sea scenes' step "
        "count; bump and the parallax family take none) against elevation: mean fetches per pixel, rmse and the "
        f"fraction of pixels off by more than 10, with the band at or below {HORIZON_BAND_DEG:g} degrees shaded.\n")
    out.append(f"![horizon band]({name})\n")
    main = info.get("main_scene", scenes[0])
    for scene in [main] + [s for s in scenes if s != main]:
        band = horizon_band(grazing, scene, steps)
        if not band:
            continue
        if scene == main:
            costs = [f"{m} x{e['ratio']:.1f} (rmse {e['base_rmse']:.2f} to {e['rmse']:.2f})"
                     for m, e in sorted(band.items(), key=lambda i: -(i[1]["ratio"] or 0)) if e["ratio"] is not None]
            out.append(
                f"Measured here on {scene}, the band ({band_elevations} degrees) against {HORIZON_BASE_DEG:g} degrees "
                f"at {steps} steps, as the ratio of mean fetches per pixel and the rmse at 45 degrees to the band's: "
                f"{', '.join(costs)}. The tables give each scene's fetches and error at both (band: the mean over its "
                "elevations).\n")
        body = [[m, f"{e['base_fetches']:.1f}", f"{e['fetches']:.1f}", "-" if e["ratio"] is None else f"{e['ratio']:.2f}",
                 f"{e['base_rmse']:.2f}", f"{e['rmse']:.2f}", f"{e['base_over']:.4f}", f"{e['over']:.4f}"]
                for m, e in band.items()]
        out.append(f"**{scene}**: the band against {HORIZON_BASE_DEG:g} degrees at {steps} steps\n")
        out.append(table(f"horizon:{scene}", ["method", f"fetches {HORIZON_BASE_DEG:g} deg", "fetches band",
                                              "fetch ratio", f"rmse {HORIZON_BASE_DEG:g} deg", "rmse band",
                                              f"off>10 {HORIZON_BASE_DEG:g} deg", "off>10 band"], body))

    # 3 bake
    out.append("## 3. The bake's accuracy and its price\n")
    name = bake_figure(directory, bake)
    scene = bake[0]["scene"] if bake else "?"
    out.append(
        f"The budgeted bakers on the {scene} map (4 sectors): by frame budget at tolerance "
        f"{info['default_tolerance']:g} (solid) and by tolerance with an unlimited budget (dotted). Left: bake time "
        "against the mean cone ratio - the tightness a ray's step length is made of. Centre cones hold between texel "
        "centres (the renderer refuses them: they are not safe for the bilinear surface it samples); bilinear cones "
        "are what the cone methods render from, and the star is the full (unbudgeted) bake_bilinear_cones, itself a "
        "lower bound of the tightest ratios. Right: "
        f"for each bilinear map, the fetches per pixel acm4 needs at the fewest steps (of {info['bake_steps'][0]}..."
        f"{info['bake_steps'][-1]}) that reach rmse <= {target:g} seen from {info['bake_view_elevation']:g} degrees "
        "- the time a tighter bake costs against what it saves in the render. Every map here is conservative, "
        "whatever its budget: a starved bake only costs steps.\n")
    out.append(f"![bake]({name})\n")
    starved = [r for r in bake if r["cones"] == "bilinear" and r["budget_ms"] != "inf" and float(r["budget_ms"]) == 0]
    full = [r for r in bake if r["cones"] == "bilinear-full"]
    if starved and full and starved[0]["acm4_fetches"] and full[0]["acm4_fetches"]:
        zero, whole = starved[0], full[0]
        out.append(
            f"Measured here: the first stage alone (budget 0) takes {float(zero['bake_ms']):.1f} ms for a mean ratio of "
            f"{float(zero['mean_ratio']):.4f}; the full bake takes {float(whole['bake_ms']):.0f} ms for "
            f"{float(whole['mean_ratio']):.4f}. acm4 then needs {float(zero['acm4_fetches']):.1f} against "
            f"{float(whole['acm4_fetches']):.1f} fetches per pixel ({zero['acm4_steps']} against "
            f"{whole['acm4_steps']} steps) for the target.\n")
        floor = float(zero["bake_ms"])
        overruns = [(float(r["bake_ms"]) - max(float(r["budget_ms"]), floor), float(r["budget_ms"])) for r in bake
                    if r["cones"] == "bilinear" and r["budget_ms"] != "inf" and float(r["budget_ms"]) > 0]
        if overruns:
            worst = max(overruns)
            out.append(f"Budgets are met to within {max(worst[0], 0):.1f} ms past the larger of the budget and the "
                       f"first stage (worst at a {worst[1]:g} ms budget).\n")
    body = []
    for r in bake:
        body.append([r["cones"], fmt_budget(number(r["budget_ms"])), r["tolerance"], f"{float(r['bake_ms']):.1f}",
                     f"{float(r['mean_ratio']):.4f}", r["texels_fallback"], r["acm4_steps"] or "-",
                     f"{float(r['acm4_fetches']):.1f}" if r["acm4_fetches"] else "-",
                     f"{float(r['acm4_ms']):.2f}" if r["acm4_ms"] else "-"])
    out.append(table("bake", ["cones", "budget ms", "tolerance", "bake ms", "mean ratio", "fallback texels",
                              "acm4 steps", "acm4 fetches", "acm4 ms"], body))

    # 4 frame
    out.append("## 4. The frame\n")
    summary = frame_summary(frame)
    name = frame_figure(directory, frame, summary)
    f = info["frame"]
    out.append(
        f"The `{f['scene']}` scene of the frame pipeline ({f['map_size']} x {f['map_size']} ocean, choppy with foam, "
        f"{f['width']} x {f['height']} pixels, {f['method']} at {f['steps']} steps) for {f['frames']} frames at each "
        "frame budget: the bake gets what the budget leaves after the other stages of the previous frame (never "
        "less than its first stage), so a tight budget renders from fallback ratios. Left: each frame's rmse "
        "against the reference rendered from the same heights and foam. Right: the median time of each stage. The "
        "table adds the frame's p95, the median mean cone ratio and the fetches per pixel the render then needed.\n")
    out.append(f"![frame]({name})\n")
    if len(summary) > 1:
        tight, loose = summary[0], summary[-1]
        out.append(
            f"Measured here: from a {fmt_budget(tight['budget'])} ms frame budget to "
            f"{fmt_budget(loose['budget']) + ' ms' if math.isfinite(loose['budget']) else 'none'}, the median mean "
            f"cone ratio goes from {tight['ratio']:.4f} to {loose['ratio']:.4f}, the fetches per pixel from "
            f"{tight['fetches']:.1f} to {loose['fetches']:.1f}, and the median rmse from {tight['rmse_median']:.3f} to "
            f"{loose['rmse_median']:.3f} (largest {tight['rmse_max']:.3f} and {loose['rmse_max']:.3f}): conservative "
            "fallback ratios cost steps, not error, while the steps last.\n")
    body = [[fmt_budget(e["budget"]), fmt_ms(e["sim"]), fmt_ms(e["bake"]), fmt_ms(e["upload"]), fmt_ms(e["render"]),
             fmt_ms(e["frame"]), fmt_ms(e["frame_p95"]), f"{e['ratio']:.4f}", f"{e['fetches']:.1f}",
             f"{e['rmse_median']:.3f}", f"{e['rmse_max']:.3f}"] for e in summary]
    out.append(table("frame", ["frame budget ms", "sim", "bake", "upload", "render", "frame", "frame p95",
                               "mean ratio", "fetches/pixel", "rmse median", "rmse max"], body))

    # 5 heatmaps
    out.append("## 5. Where the steps go\n")
    name = heatmap_figure(directory, heatmaps)
    out.append(
        f"Search iterations per pixel on the {heatmaps[0]['scene'] if heatmaps else '?'} scene's default view at "
        f"{info['heatmap_steps']} steps, one colour scale for all (black: off the relief). Linear searches spend "
        "the same steps everywhere they are allowed to; cones and pyramids spend them where rays graze crests; "
        "sphere tracing spends them near the surface.\n")
    out.append(f"![heatmaps]({name})\n")
    body = [[r["method"], r["steps"], f"{float(r['mean_iterations']):.1f}", r["max_iterations"],
             f"{float(r['mean_fetches']):.1f}", f"{float(r['rmse']):.2f}"] for r in heatmaps]
    out.append(table("heatmaps", ["method", "steps", "mean iterations", "max iterations", "fetches/pixel", "rmse"],
                     body))

    write_whole(os.path.join(directory, "README.md"), "\n".join(out).encode())


if __name__ == "__main__":
    main()
