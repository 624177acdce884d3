#!/usr/bin/env python3
"""Animated SVG (SMIL) of a piloted flight's top view from a `parapet run --pilot` report.

Reproduce docs/figures/wall_slide.svg:
    cargo run --release -p parapet-sim -- run --scene scenes/pilot/wall.toml \
        --pilot scenes/pilot/wall_slide.pilot.toml --out out/wall_slide
    python3 docs/figures/wall_slide_svg.py out/wall_slide docs/figures/wall_slide.svg

Draws (ENU top view, x east right, y north up) the scene's box obstacles, the flown track,
ghosts of the hull every second (the figure sequence) and the hull moving along the track
(10 frames per simulated second, real time), red while the safety filter changes the pilot's
command, blue otherwise; the arrow is the pilot's stick command (Position-assist velocity
direction). Standard library only.
"""
import csv
import sys
import tomllib

HULL = 0.05 ** 0.5


def main(report, out):
    rows = list(csv.DictReader(open(f"{report}/trajectory.csv")))
    pil = list(csv.DictReader(open(f"{report}/pilot.csv")))
    import json
    summ = json.load(open(f"{report}/summary.json"))
    scene = tomllib.load(open(summ["scene_file"], "rb"))
    boxes = [o for o in scene.get("obstacles", []) if o.get("kind") == "box"]
    xs = [float(r["x"]) for r in rows]
    ys = [float(r["y"]) for r in rows]
    x0, x1 = min(xs) - 1.0, max(xs) + 1.0
    y0, y1 = min(ys) - 1.0, max(max(ys), max(b["max"][1] for b in boxes) if boxes else 0) + 1.0
    s = 60.0  # px per m
    W, H = (x1 - x0) * s, (y1 - y0) * s
    X = lambda x: (x - x0) * s
    Y = lambda y: (y1 - y) * s
    o = []
    o.append(f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.0f}" height="{H + 40:.0f}" '
             f'viewBox="0 0 {W:.0f} {H + 40:.0f}" font-family="sans-serif" font-size="12">')
    o.append(f'<rect width="100%" height="100%" fill="white"/>')
    for b in boxes:
        bx0, by0 = max(b["min"][0], x0), b["min"][1]
        bx1, by1 = min(b["max"][0], x1), b["max"][1]
        o.append(f'<rect x="{X(bx0):.1f}" y="{Y(by1):.1f}" width="{(bx1 - bx0) * s:.1f}" '
                 f'height="{(by1 - by0) * s:.1f}" fill="#888"/>')
        o.append(f'<text x="{X(bx0) + 4:.1f}" y="{Y(by1) - 4:.1f}">{b.get("name", "box")}</text>')
    pts = " ".join(f"{X(x):.1f},{Y(y):.1f}" for x, y in zip(xs, ys))
    o.append(f'<polyline points="{pts}" fill="none" stroke="#36c" stroke-width="1.5"/>')
    # Figure sequence: ghosts every second.
    t_end = float(rows[-1]["t"])
    for k in range(int(t_end) + 1):
        r = min(rows, key=lambda r: abs(float(r["t"]) - k))
        c = "#d33" if r["filter_active"] == "1" else "#36c"
        o.append(f'<circle cx="{X(float(r["x"])):.1f}" cy="{Y(float(r["y"])):.1f}" r="{HULL * s:.1f}" '
                 f'fill="{c}" fill-opacity="0.15" stroke="{c}" stroke-opacity="0.5"/>')
        o.append(f'<text x="{X(float(r["x"])) + HULL * s + 2:.1f}" y="{Y(float(r["y"])) + 4:.1f}" '
                 f'fill="#555" font-size="10">{k} s</text>')
    # Animation at 10 frames per second.
    frames = [min(range(len(rows)), key=lambda i: abs(float(rows[i]["t"]) - j / 10))
              for j in range(int(t_end * 10) + 1)]
    dur = f"{t_end:.1f}s"
    cx = ";".join(f"{X(xs[i]):.1f}" for i in frames)
    cy = ";".join(f"{Y(ys[i]):.1f}" for i in frames)
    fill = ";".join("#d33" if rows[i]["filter_active"] == "1" else "#36c" for i in frames)
    o.append(f'<circle r="{HULL * s:.1f}" fill="#36c" stroke="black">'
             f'<animate attributeName="cx" values="{cx}" dur="{dur}" repeatCount="indefinite"/>'
             f'<animate attributeName="cy" values="{cy}" dur="{dur}" repeatCount="indefinite"/>'
             f'<animate attributeName="fill" values="{fill}" dur="{dur}" calcMode="discrete" '
             f'repeatCount="indefinite"/></circle>')
    # Stick arrow (Position-assist: pitch forward = north, roll right = east at heading north).
    ptimes = [float(p["t"]) for p in pil]
    def stick(i):
        t = float(rows[i]["t"])
        j = min(range(len(pil)), key=lambda k: abs(ptimes[k] - t))
        p = pil[j]
        if p["rc"] != "1":
            return 0.0, 0.0
        return float(p["roll"]), float(p["pitch"])
    x2 = ";".join(f"{X(xs[i] + stick(i)[0]):.1f}" for i in frames)
    y2 = ";".join(f"{Y(ys[i] + stick(i)[1]):.1f}" for i in frames)
    o.append(f'<line stroke="#393" stroke-width="2.5" x1="0" y1="0" x2="0" y2="0">'
             f'<animate attributeName="x1" values="{cx}" dur="{dur}" repeatCount="indefinite"/>'
             f'<animate attributeName="y1" values="{cy}" dur="{dur}" repeatCount="indefinite"/>'
             f'<animate attributeName="x2" values="{x2}" dur="{dur}" repeatCount="indefinite"/>'
             f'<animate attributeName="y2" values="{y2}" dur="{dur}" repeatCount="indefinite"/></line>')
    # Time bar.
    o.append(f'<rect x="0" y="{H + 28:.0f}" height="6" width="0" fill="#393">'
             f'<animate attributeName="width" values="0;{W:.0f}" dur="{dur}" repeatCount="indefinite"/></rect>')
    mc = summ["min_clearance_m"]
    o.append(f'<text x="6" y="{H + 20:.0f}">{summ["scene"]}, pilot {summ["pilot"]["name"]}: track (blue), hull every 1 s, '
             f'red = filter changing the command, green = stick; min clearance {mc:.3f} m, '
             f'{t_end:.0f} s, collided {str(summ["collided"]).lower()}</text>')
    o.append("</svg>")
    open(out, "w").write("\n".join(o) + "\n")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
