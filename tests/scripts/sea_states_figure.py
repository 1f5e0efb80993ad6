#!/usr/bin/env python3
"""tests/scripts/sea_states_figure.py - the sea-state figures of docs/figures.md, from `displace sim`.

  docs/sea/hs_fetch.svg  Hs against fetch at 10 m/s: the Hs synthesized (4 sigma of the heights, the mean
                         over seeds) against JONSWAP's fetch law and the Pierson-Moskowitz limit.
  docs/sea/spectra.svg   each spectrum's synthesized S(f) (the modes' energy in bins 3% wide, the mean over
                         seeds; `sim --frequency-spectrum`) against the analytic one.

usage: tests/scripts/sea_states_figure.py DISPLACE_BINARY [OUT_DIR (default docs/sea)] [--quick]
  --quick: two fetches, one seed, 64-sample maps (the suite runs this into a temporary folder, to keep
  the script working); the figures in docs/ are the full run's.

Standard library only: the SVG is written by hand, atomically (a temporary file, fsync, rename).
"""
import math
import os
import re
import subprocess
import sys
import tempfile

GRAVITY = 9.81
WIND = 10.0  # m/s
PM_HS = 4.0 * math.sqrt(0.0081 / (5.0 * 0.855 ** 4)) * WIND * WIND / GRAVITY  # 0.2202 U^2 / g


def jonswap_law(fetch_km):
    """Hs and w_p of JONSWAP's fetch laws (Hasselmann et al. 1973) at WIND, uncapped."""
    chi = GRAVITY * fetch_km * 1000.0 / (WIND * WIND)
    hs = 4.0 * math.sqrt(1.6e-7 * chi) * WIND * WIND / GRAVITY
    peak = 22.0 * GRAVITY / WIND * chi ** (-1.0 / 3.0)
    return hs, peak


def run_sim(displace, flags, workdir):
    command = [displace, "sim", "--output", os.path.join(workdir, "h.exr")] + flags
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    if result.returncode != 0:
        sys.exit("sea_states_figure: %s failed:\n%s" % (" ".join(command), result.stderr))
    return result.stdout


def number_after(pattern, text):
    match = re.search(pattern, text)
    if not match:
        sys.exit("sea_states_figure: no %r in:\n%s" % (pattern, text))
    return float(match.group(1))


def read_csv(path):
    with open(path, encoding="utf-8") as stream:
        rows = [line.strip().split(",") for line in stream if line.strip()]
    return [[float(value) for value in row] for row in rows[1:]]


def write_atomically(path, text):
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=folder, prefix=".sea_states_")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise
    directory = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)


class LogPlot:
    """An SVG plot with log axes: x in [x0, x1], y in [y0, y1]."""

    def __init__(self, title, x_label, y_label, x_range, y_range, width=640, height=420):
        self.width, self.height = width, height
        self.left, self.right, self.top, self.bottom = 70, 20, 36, 52
        self.x_range, self.y_range = x_range, y_range
        self.items = []
        self.legend = []
        self.items.append('<text x="%d" y="22" font-size="15" text-anchor="middle">%s</text>' %
                          (width // 2, title))
        self.items.append('<text x="%d" y="%d" font-size="13" text-anchor="middle">%s</text>' %
                          ((self.left + width - self.right) // 2, height - 12, x_label))
        self.items.append('<text x="16" y="%d" font-size="13" text-anchor="middle" '
                          'transform="rotate(-90 16 %d)">%s</text>' %
                          ((self.top + height - self.bottom) // 2, (self.top + height - self.bottom) // 2,
                           y_label))
        self.axes()

    def px(self, x):
        low, high = (math.log10(v) for v in self.x_range)
        return self.left + (math.log10(x) - low) / (high - low) * (self.width - self.left - self.right)

    def py(self, y):
        low, high = (math.log10(v) for v in self.y_range)
        return self.height - self.bottom - (math.log10(y) - low) / (high - low) * (
            self.height - self.top - self.bottom)

    def axes(self):
        x0, x1 = self.left, self.width - self.right
        y0, y1 = self.top, self.height - self.bottom
        self.items.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="black"/>' %
                          (x0, y0, x1 - x0, y1 - y0))
        for axis, (low, high) in (("x", self.x_range), ("y", self.y_range)):
            for exponent in range(math.floor(math.log10(low)), math.ceil(math.log10(high)) + 1):
                for mantissa in (1, 2, 5):
                    value = mantissa * 10.0 ** exponent
                    if not low <= value <= high:
                        continue
                    label = "%g" % value
                    if axis == "x":
                        x = self.px(value)
                        self.items.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#ddd"/>' %
                                          (x, y0, x, y1))
                        self.items.append('<text x="%.1f" y="%d" font-size="11" text-anchor="middle">%s'
                                          '</text>' % (x, y1 + 15, label))
                    else:
                        y = self.py(value)
                        self.items.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#ddd"/>' %
                                          (x0, y, x1, y))
                        self.items.append('<text x="%d" y="%.1f" font-size="11" text-anchor="end">%s'
                                          '</text>' % (x0 - 5, y + 4, label))

    def line(self, points, colour, label, dash=None):
        inside = [(x, y) for x, y in points if x > 0 and y > 0]
        path = " ".join("%.1f,%.1f" % (self.px(x), self.py(y)) for x, y in inside)
        style = ' stroke-dasharray="%s"' % dash if dash else ""
        self.items.append('<polyline points="%s" fill="none" stroke="%s" stroke-width="1.6"%s/>' %
                          (path, colour, style))
        self.legend.append((label, colour, "line", dash))

    def dots(self, points, colour, label):
        for x, y in points:
            if x > 0 and y > 0:
                self.items.append('<circle cx="%.1f" cy="%.1f" r="3.2" fill="%s"/>' %
                                  (self.px(x), self.py(y), colour))
        self.legend.append((label, colour, "dot", None))

    def svg(self):
        x0, x1 = self.left, self.width - self.right
        y0, y1 = self.top, self.height - self.bottom
        clip = ('<clipPath id="plot"><rect x="%d" y="%d" width="%d" height="%d"/></clipPath>' %
                (x0, y0, x1 - x0, y1 - y0))
        entries = []
        for row, (label, colour, kind, dash) in enumerate(self.legend):
            y = self.top + 16 + 17 * row
            x = self.width - self.right - 250
            if kind == "dot":
                entries.append('<circle cx="%d" cy="%d" r="3.2" fill="%s"/>' % (x + 10, y - 4, colour))
            else:
                style = ' stroke-dasharray="%s"' % dash if dash else ""
                entries.append('<line x1="%d" y1="%d" x2="%d" y2="%d" stroke="%s" stroke-width="1.6"%s/>' %
                               (x, y - 4, x + 20, y - 4, colour, style))
            entries.append('<text x="%d" y="%d" font-size="12">%s</text>' % (x + 26, y, label))
        axes = [item for item in self.items if not item.startswith(("<polyline", "<circle"))]
        data = [item for item in self.items if item.startswith(("<polyline", "<circle"))]
        return ('<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif">\n'
                '<rect width="100%%" height="100%%" fill="white"/>\n%s\n%s\n<g clip-path="url(#plot)">\n%s\n'
                '</g>\n%s\n</svg>\n' % (self.width, self.height, clip, "\n".join(axes), "\n".join(data),
                                         "\n".join(entries)))


def hs_against_fetch(displace, workdir, quick):
    fetches = [2.0, 10000.0] if quick else [
        1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0, 10000.0]
    seeds = 1 if quick else 16
    size = 64 if quick else 256
    measured = []
    for index, fetch in enumerate(fetches):
        _, peak = jonswap_law(min(fetch, 1.7e4 * WIND * WIND / GRAVITY / 1000.0))
        wavelength = 2.0 * math.pi * GRAVITY / (max(peak, 0.855 * GRAVITY / WIND) ** 2)
        patch = 8.0 * wavelength  # eight peak wavelengths: the lattice holds the peak within 1%
        heights = []
        for seed in range(seeds):
            out = run_sim(displace, ["--spectrum", "jonswap", "--wind-speed", "%g" % WIND, "--fetch", "%g" % fetch,
                                     "--patch-size", "%.1f" % patch, "--map-size", str(size), "--seed",
                                     str(100 * index + seed + 1), "--choppiness", "0"], workdir)
            heights.append(number_after(r"([0-9.]+) m in these heights", out) ** 2)
        measured.append((fetch, math.sqrt(sum(heights) / len(heights))))
    curve = [(10.0 ** (e / 20.0), jonswap_law(10.0 ** (e / 20.0))[0]) for e in range(0, 81)]
    plot = LogPlot("Hs against fetch, U10 = %g m/s (JONSWAP)" % WIND, "fetch (km)", "Hs (m)", (1.0, 1e4),
                   (0.1, 10.0))
    plot.line(curve, "#1f77b4", "JONSWAP fetch law 1.6e-7 g F / U^2", dash="6,4")
    plot.line([(1.0, PM_HS), (1e4, PM_HS)], "#d62728", "Pierson-Moskowitz limit %.2f m" % PM_HS)
    plot.dots(measured, "black", "synthesized (4 sigma, %d seeds)" % seeds)
    return plot.svg(), measured


def spectra(displace, workdir, quick):
    seeds = 1 if quick else 8
    size = 64 if quick else 512
    cases = [
        ("phillips", ["--spectrum", "phillips", "--wind-speed", "10"], "#7f7f7f"),
        ("pierson-moskowitz", ["--spectrum", "pierson-moskowitz", "--wind-speed", "10"], "#d62728"),
        ("jonswap 50 km", ["--spectrum", "jonswap", "--wind-speed", "10", "--fetch", "50"], "#1f77b4"),
        ("tma 50 km, 4 m deep", ["--spectrum", "tma", "--wind-speed", "10", "--fetch", "50", "--depth", "4"],
         "#2ca02c"),
    ]
    plot = LogPlot("S(f): synthesized (dots) against analytic (lines), U10 = 10 m/s", "f (Hz)",
                   "S (m^2 / Hz)", (0.05, 2.0), (1e-4, 10.0))
    for name, flags, colour in cases:
        sums = {}
        analytic = {}
        for seed in range(seeds):
            csv = os.path.join(workdir, "s.csv")
            run_sim(displace, flags + ["--patch-size", "1000", "--map-size", str(size), "--seed", str(seed + 1),
                                       "--choppiness", "0", "--frequency-spectrum", csv], workdir)
            for frequency, synthesized, exact, _modes in read_csv(csv):
                key = round(frequency, 6)
                sums[key] = sums.get(key, 0.0) + synthesized / seeds
                analytic[key] = exact
        keys = sorted(sums)
        plot.line([(f, analytic[f]) for f in keys], colour, name)
        plot.dots([(f, sums[f]) for f in keys], colour, "")
        plot.legend.pop()
    return plot.svg()


def main():
    arguments = [a for a in sys.argv[1:] if a != "--quick"]
    quick = "--quick" in sys.argv[1:]
    if not arguments:
        sys.exit(__doc__)
    displace = arguments[0]
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out_dir = arguments[1] if len(arguments) > 1 else os.path.join(root, "docs", "sea")
    with tempfile.TemporaryDirectory() as workdir:
        hs_svg, measured = hs_against_fetch(displace, workdir, quick)
        spectra_svg = spectra(displace, workdir, quick)
    write_atomically(os.path.join(out_dir, "hs_fetch.svg"), hs_svg)
    write_atomically(os.path.join(out_dir, "spectra.svg"), spectra_svg)
    for fetch, hs in measured:
        law, _ = jonswap_law(fetch)
        print("fetch %8g km: Hs synthesized %.3f m, JONSWAP law %.3f m, PM %.3f m" % (fetch, hs, law, PM_HS))
    print("sea_states_figure: wrote %s and %s" % (os.path.join(out_dir, "hs_fetch.svg"),
                                                  os.path.join(out_dir, "spectra.svg")))


if __name__ == "__main__":
    main()
