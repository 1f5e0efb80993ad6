#!/usr/bin/env python3
"""Checks a `displace report` directory: every promised figure exists and is a valid PNG, and every
number in README.md's tables is what the CSVs next to it say. Written apart from the plotting
script: each table is recomputed here from the CSVs with its own code.

    python3 tests/report_check.py DIR
Exits 1 with one line per problem.
"""
import csv
import json
import math
import os
import re
import struct
import sys
import zlib

problems = []


def problem(text):
    problems.append(text)


def check_png(path):
    """PNG signature, every chunk's CRC, IHDR first with a non-empty size, IEND last."""
    try:
        data = open(path, "rb").read()
    except OSError as error:
        problem(f"{path}: cannot read ({error})")
        return
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        problem(f"{path}: not a PNG (signature)")
        return
    offset, chunks = 8, []
    while offset + 12 <= len(data):
        length, kind = struct.unpack(">I4s", data[offset:offset + 8])
        body = data[offset + 8:offset + 8 + length]
        crc = data[offset + 8 + length:offset + 12 + length]
        if len(body) != length or len(crc) != 4:
            problem(f"{path}: chunk {kind!r} is cut short")
            return
        if zlib.crc32(kind + body) & 0xFFFFFFFF != struct.unpack(">I", crc)[0]:
            problem(f"{path}: chunk {kind!r} has a bad CRC")
            return
        chunks.append((kind, body))
        offset += 12 + length
    if not chunks or chunks[0][0] != b"IHDR" or chunks[-1][0] != b"IEND":
        problem(f"{path}: IHDR is not first or IEND not last")
        return
    width, height = struct.unpack(">II", chunks[0][1][:8])
    if width == 0 or height == 0:
        problem(f"{path}: empty image")
    if not any(kind == b"IDAT" for kind, _ in chunks):
        problem(f"{path}: no image data")


def read_csv(directory, name):
    with open(os.path.join(directory, name), newline="") as handle:
        return list(csv.DictReader(handle))


def read_tables(readme):
    """{name: [row cells]} for every table after a `<!-- table:NAME -->` marker."""
    tables, lines, i = {}, readme.splitlines(), 0
    while i < len(lines):
        marker = re.match(r"<!-- table:(\S+) -->", lines[i])
        i += 1
        if not marker:
            continue
        rows = []
        while i < len(lines) and lines[i].startswith("|"):
            rows.append([cell.strip() for cell in lines[i].strip().strip("|").split("|")])
            i += 1
        tables[marker.group(1)] = rows[2:]  # past the header and the rule
    return tables


def close(cell, value, places):
    """A table cell printed with `places` decimals holds `value`."""
    try:
        return abs(float(cell) - value) <= 0.5 * 10 ** -places + 1e-9
    except ValueError:
        return False


def decimals(cell):
    return len(cell.split(".")[1]) if "." in cell else 0


def median(values):
    ordered = sorted(values)
    middle = len(ordered) // 2
    return ordered[middle] if len(ordered) % 2 else (ordered[middle - 1] + ordered[middle]) / 2


def main():
    directory = sys.argv[1]
    info = json.load(open(os.path.join(directory, "report.json")))
    readme = open(os.path.join(directory, "README.md")).read()
    target = float(info["target_rmse"])

    # figures: each promised one is embedded and valid; so are the heatmap data images
    promised = [f"cost_{scene}.png" for scene in info["scenes"]] + ["grazing.png", "horizon.png", "bake.png",
                                                                     "frame.png", "heatmaps.png"]
    embedded = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme)
    for figure in promised:
        if figure not in embedded:
            problem(f"README.md does not embed {figure}")
        check_png(os.path.join(directory, figure))
    for figure in embedded:
        if figure not in promised:
            check_png(os.path.join(directory, figure))
    heatmaps = read_csv(directory, "heatmaps.csv")
    for row in heatmaps:
        check_png(os.path.join(directory, row["file"]))

    tables = read_tables(readme)
    cost = read_csv(directory, "cost.csv")
    grazing = read_csv(directory, "grazing.csv")
    bake = read_csv(directory, "bake.csv")
    frame = read_csv(directory, "frame.csv")

    # best:SCENE - each method once: the fewest fetches among its rows within the target
    for scene in info["scenes"]:
        name = f"best:{scene}"
        if name not in tables:
            problem(f"README.md has no table {name}")
            continue
        rows = [r for r in cost if r["scene"] == scene]
        methods = {r["method"] for r in rows}
        seen = set()
        for method, steps, fetches, ms, rmse in tables[name]:
            seen.add(method)
            within = [r for r in rows if r["method"] == method and float(r["rmse"]) <= target]
            if steps == "-":
                if within:
                    problem(f"{name}: {method} reaches rmse <= {target:g} in cost.csv but the table says not")
                continue
            if not within:
                problem(f"{name}: {method} never reaches the target in cost.csv but the table gives {steps} steps")
                continue
            fewest = min(float(r["mean_fetches"]) for r in within)
            chosen = [r for r in within if float(r["mean_fetches"]) == fewest]
            if not close(fetches, fewest, decimals(fetches)):
                problem(f"{name}: {method} fetches {fetches}, cost.csv says {fewest}")
            if not any(r["steps"] == steps and close(ms, float(r["median_ms"]), decimals(ms))
                       and close(rmse, float(r["rmse"]), decimals(rmse)) for r in chosen):
                problem(f"{name}: {method} steps/ms/rmse {steps}/{ms}/{rmse} are not cost.csv's")
        if seen != methods:
            problem(f"{name}: methods {sorted(methods ^ seen)} are missing or extra")

    # per plane scene, from grazing.csv:
    # grazing:SCENE - fewest steps within the target per method and elevation
    # decide:SCENE - per elevation and target, the fewest fetches of any method reaching the target
    for scene in info["scenes"]:
        rows = [r for r in grazing if r["scene"] == scene]
        if not rows:
            continue
        missing = [n for n in (f"grazing:{scene}", f"decide:{scene}") if n not in tables]
        for name in missing:
            problem(f"README.md has no table {name}")
        if missing:
            continue
        name = f"grazing:{scene}"
        elevations = sorted({float(r["elevation_deg"]) for r in rows})
        for cells in tables[name]:
            method = cells[0]
            for elevation, cell in zip(elevations, cells[1:]):
                steps = [int(r["steps"]) for r in rows if r["method"] == method
                         and float(r["elevation_deg"]) == elevation and float(r["rmse"]) <= target]
                expected = str(min(steps)) if steps else "-"
                if cell != expected:
                    problem(f"{name}: {method} at {elevation:g} degrees says {cell}, grazing.csv gives {expected}")
        name = f"decide:{scene}"
        for elevation_cell, goal_cell, method, steps, fetches, ms in tables[name]:
            at = [r for r in rows if float(r["elevation_deg"]) == float(elevation_cell)
                  and float(r["rmse"]) <= float(goal_cell)]
            if method == "-":
                if at:
                    problem(f"{name}: {elevation_cell} deg, rmse {goal_cell}: grazing.csv has runs that reach it")
                continue
            fewest = min((float(r["mean_fetches"]) for r in at), default=None)
            if fewest is None or not close(fetches, fewest, decimals(fetches)):
                problem(f"{name}: {elevation_cell} deg, rmse {goal_cell}: {fetches} fetches, grazing.csv's fewest "
                        f"is {fewest}")
            if not any(r["method"] == method and r["steps"] == steps and float(r["mean_fetches"]) == fewest
                       for r in at):
                problem(f"{name}: {elevation_cell} deg, rmse {goal_cell}: {method} at {steps} steps is not a run "
                        "with the fewest fetches")

    # grazing.csv's views: every promised elevation, down to 0.5 degrees, each one seeing the relief
    side = int(info["image_side"])
    for scene in {r["scene"] for r in grazing}:
        rows = [r for r in grazing if r["scene"] == scene]
        elevations = sorted({float(r["elevation_deg"]) for r in rows})
        if elevations != sorted(float(e) for e in info["elevations"]):
            problem(f"grazing.csv: {scene} has elevations {elevations}, report.json promises {info['elevations']}")
        if not elevations or elevations[0] > 0.5:
            problem(f"grazing.csv: {scene} does not go down to 0.5 degrees (lowest {elevations[:1]})")
        for elevation in elevations:
            hits = {int(r["reference_pixels"]) for r in rows if float(r["elevation_deg"]) == elevation}
            if len(hits) != 1 or min(hits) < side * side // 10:
                problem(f"grazing.csv: {scene} at {elevation:g} degrees: the reference hits {sorted(hits)} pixels "
                        f"of {side * side}, not one count of at least a tenth")

    # horizon:SCENE - per method at horizon_steps (or its only row): means over the elevations <= 2 degrees
    # against the row at 45 degrees
    steps = int(info["horizon_steps"])
    if steps not in info["grazing_steps"]:
        problem(f"report.json: horizon_steps {steps} is not one of grazing_steps")
    for scene in info["scenes"]:
        rows = [r for r in grazing if r["scene"] == scene]
        if not rows:
            continue
        name = f"horizon:{scene}"
        if name not in tables:
            problem(f"README.md has no table {name}")
            continue
        methods = []
        for cells in tables[name]:
            method, base_fetches, fetches, ratio, base_rmse, rmse, base_over, over = cells
            methods.append(method)
            mine = [r for r in rows if r["method"] == method]
            if len({r["steps"] for r in mine}) > 1:
                mine = [r for r in mine if int(r["steps"]) == steps]
            band = [r for r in mine if float(r["elevation_deg"]) <= 2.0]
            base = [r for r in mine if float(r["elevation_deg"]) == 45.0]
            if len(base) != 1 or len(band) != len({float(e) for e in info["elevations"] if float(e) <= 2.0}):
                problem(f"{name}: {method} has {len(base)} rows at 45 degrees and {len(band)} in the band")
                continue
            mean = lambda column: sum(float(r[column]) for r in band) / len(band)  # noqa: E731
            expected = [(base_fetches, float(base[0]["mean_fetches"])), (fetches, mean("mean_fetches")),
                        (base_rmse, float(base[0]["rmse"])), (rmse, mean("rmse")),
                        (base_over, float(base[0]["fraction_over_10"])), (over, mean("fraction_over_10"))]
            if float(base[0]["mean_fetches"]) > 0:
                expected.append((ratio, mean("mean_fetches") / float(base[0]["mean_fetches"])))
            elif ratio != "-":
                problem(f"{name}: {method} has no fetches at 45 degrees but a ratio {ratio}")
            for cell, value in expected:
                if not close(cell, value, decimals(cell)):
                    problem(f"{name}: {method} says {cell} where grazing.csv gives {value}")
            # the paragraph's ratio for the main scene, where it names this method
            said = re.search(rf"(?<![\w-]){re.escape(method)} x([0-9.]+) \(rmse ([0-9.]+) to ([0-9.]+)\)", readme) if scene == info["main_scene"] else None
            if scene == info["main_scene"] and float(base[0]["mean_fetches"]) > 0 and (
                    not said or not close(said.group(1), mean("mean_fetches") / float(base[0]["mean_fetches"]),
                                          decimals(said.group(1)))
                    or not close(said.group(2), float(base[0]["rmse"]), decimals(said.group(2)))
                    or not close(said.group(3), mean("rmse"), decimals(said.group(3)))):
                problem(f"README.md: the band's text for {method} ({said.group(0) if said else 'missing'}) is not "
                        f"grazing.csv's x{mean('mean_fetches') / float(base[0]['mean_fetches'])}")
        if sorted(methods) != sorted({r["method"] for r in rows}):
            problem(f"{name}: methods {sorted(set(methods) ^ {r['method'] for r in rows})} are missing or extra")

    # bake - one row per bake.csv row, in order
    if len(tables.get("bake", [])) != len(bake):
        problem(f"bake: {len(tables.get('bake', []))} rows, bake.csv has {len(bake)}")
    for cells, row in zip(tables.get("bake", []), bake):
        kind, budget, tolerance, bake_ms, ratio, fallback, steps, fetches, ms = cells
        budget_ok = (budget == "unlimited") == (row["budget_ms"] == "inf") and (
            budget == "unlimited" or float(budget) == float(row["budget_ms"]))
        if (kind != row["cones"] or not budget_ok or float(tolerance) != float(row["tolerance"])
                or not close(bake_ms, float(row["bake_ms"]), decimals(bake_ms))
                or not close(ratio, float(row["mean_ratio"]), decimals(ratio))
                or fallback != row["texels_fallback"] or steps != (row["acm4_steps"] or "-")
                or (fetches == "-") != (not row["acm4_fetches"])
                or (fetches != "-" and not close(fetches, float(row["acm4_fetches"]), decimals(fetches)))):
            problem(f"bake: row {cells} is not bake.csv's {row}")

    # frame - medians per frame budget
    budgets = []
    for row in frame:
        if row["frame_budget_ms"] not in budgets:
            budgets.append(row["frame_budget_ms"])
    if len(tables.get("frame", [])) != len(budgets):
        problem(f"frame: {len(tables.get('frame', []))} rows for {len(budgets)} frame budgets")
    for cells, budget in zip(tables.get("frame", []), budgets):
        rows = [r for r in frame if r["frame_budget_ms"] == budget]
        expected = {
            1: median(float(r["sim_ms"]) for r in rows), 2: median(float(r["bake_ms"]) for r in rows),
            3: median(float(r["upload_ms"]) for r in rows), 4: median(float(r["render_ms"]) for r in rows),
            5: median(float(r["frame_ms"]) for r in rows), 7: median(float(r["mean_ratio"]) for r in rows),
            8: median(float(r["mean_fetches"]) for r in rows), 9: median(float(r["rmse"]) for r in rows),
            10: max(float(r["rmse"]) for r in rows)}
        frames = sorted(float(r["frame_ms"]) for r in rows)
        p95 = frames[min(len(frames) - 1, math.ceil(0.95 * len(frames)) - 1)]
        if (cells[0] == "unlimited") != (budget == "inf") or (budget != "inf" and float(cells[0]) != float(budget)):
            problem(f"frame: row {cells[0]} is not budget {budget}")
        for column, value in expected.items():
            if not close(cells[column], value, decimals(cells[column])):
                problem(f"frame: budget {budget} column {column} says {cells[column]}, frame.csv gives {value}")
        if not close(cells[6], p95, decimals(cells[6])):
            problem(f"frame: budget {budget} p95 says {cells[6]}, frame.csv gives {p95}")
        if len(rows) != int(info["frame"]["frames"]):
            problem(f"frame: budget {budget} has {len(rows)} frames, report.json promises {info['frame']['frames']}")

    # heatmaps - one row per heatmaps.csv row
    if len(tables.get("heatmaps", [])) != len(heatmaps):
        problem(f"heatmaps: {len(tables.get('heatmaps', []))} rows, heatmaps.csv has {len(heatmaps)}")
    for cells, row in zip(tables.get("heatmaps", []), heatmaps):
        method, steps, mean_iterations, max_iterations, fetches, rmse = cells
        if (method != row["method"] or steps != row["steps"]
                or not close(mean_iterations, float(row["mean_iterations"]), decimals(mean_iterations))
                or max_iterations != row["max_iterations"]
                or not close(fetches, float(row["mean_fetches"]), decimals(fetches))
                or not close(rmse, float(row["rmse"]), decimals(rmse))):
            problem(f"heatmaps: row {cells} is not heatmaps.csv's {row}")

    for line in problems:
        print(f"report_check: {line}")
    if problems:
        sys.exit(1)
    print(f"report_check: {len(promised)} figures and {len(tables)} tables agree with the data in {directory}")


if __name__ == "__main__":
    main()
