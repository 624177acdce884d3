#!/usr/bin/env python3
"""Reference: OMPL's RRT-Connect + simplifySolution on Parapet's scenes.

The paper planned with OMPL; issue 5 asks Parapet's planner for paths no
longer than a simplified OMPL RRT-Connect path. This script plans every
shipped scene with OMPL (Python bindings, `pip install ompl`) on the same
configuration space (centre of mass in the scene bounds, clearance >= hull
radius + 0.05 m margin) and prints the median path length, waypoint count and
planning + simplification time per scene, for comparison with the table that
`cargo bench -p parapet-sim --bench planner` prints.

OMPL checks motions by sampling at 1 % of the space extent (its default);
validity is evaluated in Python, so OMPL's *times* here are far slower than
native OMPL and are printed for completeness only: compare lengths.

Large scenes (issue 18: `parapet scene generate`, 10^3..10^5 obstacles): the
validity checker looks obstacles up in a uniform grid of CELL m cells over x/y
(each obstacle listed in every cell its bounds + the clearance touch), so it
evaluates the same distances as a full scan would need, only for the nearby
obstacles. `--resolution M` sets OMPL's motion-check step to M metres (OMPL's
default, 1 % of the largest extent, is 14 m on a 1.4 km forest and would step
over 0.2 m trunks); `--time-limit S` is OMPL's solve budget (default 5 s).

Usage: python3 host-sim/benches/ompl_reference.py [--runs N] [--resolution M]
       [--time-limit S] [scenes/*.toml]
"""

import argparse
import glob
import math
import os
import statistics
import time
import tomllib

from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

MARGIN = 0.05
DEFAULT_HULL = math.sqrt(0.05)


def sd_sphere(p, c, r):
    return math.dist(p, c) - r


def sd_box(p, lo, hi):
    # Exact signed distance to an axis-aligned box.
    q = [max(lo[i] - p[i], 0.0, p[i] - hi[i]) for i in range(3)]
    out = math.sqrt(sum(x * x for x in q))
    if out > 0.0:
        return out
    return -min(min(p[i] - lo[i], hi[i] - p[i]) for i in range(3))


def sd_cylinder(p, base, r, h):
    # Vertical cylinder, ENU: base disc centre, extends up by h.
    dr = math.hypot(p[0] - base[0], p[1] - base[1]) - r
    dz = max(base[2] - p[2], p[2] - (base[2] + h))
    if dr <= 0.0 and dz <= 0.0:
        return max(dr, dz)
    return math.hypot(max(dr, 0.0), max(dz, 0.0))


def load(path):
    with open(path, "rb") as f:
        s = tomllib.load(f)
    hull = s.get("vehicle", {}).get("hull_radius", DEFAULT_HULL)
    required = hull + MARGIN
    obstacles = []
    for o in s.get("obstacles", []):
        if "velocity" in o or "waypoints" in o:
            continue  # moving obstacles are ignored by the planner
        k = o["kind"]
        if k == "sphere":
            c, r = o["center"], o["radius"]
            f = lambda p, c=c, r=r: sd_sphere(p, c, r)
            box = ([c[i] - r for i in range(3)], [c[i] + r for i in range(3)])
        elif k == "box":
            f = lambda p, lo=o["min"], hi=o["max"]: sd_box(p, lo, hi)
            box = (o["min"], o["max"])
        elif k == "cylinder":
            b, r, h = o["base"], o["radius"], o["height"]
            f = lambda p, b=b, r=r, h=h: sd_cylinder(p, b, r, h)
            box = ([b[0] - r, b[1] - r, b[2]], [b[0] + r, b[1] + r, b[2] + h])
        else:
            continue
        obstacles.append((f, box))
    return s, Grid(obstacles, required), required


CELL = 4.0


class Grid:
    """Obstacles by x/y cell: each listed in every cell its box + `required` touches."""

    def __init__(self, obstacles, required):
        self.cells = {}
        for f, (lo, hi) in obstacles:
            for i in range(math.floor((lo[0] - required) / CELL), math.floor((hi[0] + required) / CELL) + 1):
                for j in range(math.floor((lo[1] - required) / CELL), math.floor((hi[1] + required) / CELL) + 1):
                    self.cells.setdefault((i, j), []).append(f)

    def near(self, p):
        return self.cells.get((math.floor(p[0] / CELL), math.floor(p[1] / CELL)), ())


def plan(scene, grid, required, seed, resolution, time_limit):
    ou.RNG.setSeed(seed)
    space = ob.RealVectorStateSpace(3)
    bounds = ob.RealVectorBounds(3)
    for i in range(3):
        bounds.setLow(i, scene["bounds"]["min"][i])
        bounds.setHigh(i, scene["bounds"]["max"][i])
    space.setBounds(bounds)
    ss = og.SimpleSetup(space)

    def valid(state):
        p = (state[0], state[1], state[2])
        return all(f(p) >= required for f in grid.near(p))

    ss.setStateValidityChecker(valid)
    if resolution:
        extent = max(scene["bounds"]["max"][i] - scene["bounds"]["min"][i] for i in range(3))
        ss.getSpaceInformation().setStateValidityCheckingResolution(resolution / extent)
    start, goal = space.allocState(), space.allocState()
    for i in range(3):
        start[i] = scene["mission"]["start"][i]
        goal[i] = scene["mission"]["goal"][i]
    ss.setStartAndGoalStates(start, goal)
    ss.setPlanner(og.RRTConnect(ss.getSpaceInformation()))
    t0 = time.perf_counter()
    solved = ss.solve(time_limit)
    if not solved or not ss.haveExactSolutionPath():
        return None
    ss.simplifySolution()
    dt = (time.perf_counter() - t0) * 1e3
    path = ss.getSolutionPath()
    n = path.getStateCount()
    return path.length(), n, dt


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=50)
    ap.add_argument("--resolution", type=float, default=None, help="motion-check step, m (default OMPL's 1 %%)")
    ap.add_argument("--time-limit", type=float, default=5.0, help="OMPL solve budget, s")
    ap.add_argument("scenes", nargs="*")
    args = ap.parse_args()
    here = os.path.dirname(os.path.abspath(__file__))
    files = args.scenes or sorted(glob.glob(os.path.join(here, "..", "..", "scenes", "*.toml")))
    ou.setLogLevel(ou.LOG_WARN)
    print(f"{'scene':<16} {'runs':>5} {'med_len_m':>10} {'mean_len_m':>11} {'med_wps':>8} {'med_ms(py)':>11}")
    for f in files:
        scene, grid, required = load(f)
        runs = (plan(scene, grid, required, seed + 1, args.resolution, args.time_limit) for seed in range(args.runs))
        res = [r for r in runs if r]
        if not res:
            print(f"{scene['name']:<16} no solution")
            continue
        lens = [r[0] for r in res]
        print(
            f"{scene['name']:<16} {len(res):>2}/{args.runs:<2} {statistics.median(lens):>10.2f} {statistics.mean(lens):>11.2f} "
            f"{statistics.median(r[1] for r in res):>8.0f} {statistics.median(r[2] for r in res):>11.1f}"
        )


if __name__ == "__main__":
    main()
