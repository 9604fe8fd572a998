#!/usr/bin/env python3
"""Writes a contact scene of N balls for the large-contact path (docs/scaling.md).

  stack   N balls of radius r resting on a floor, each on the one below (all contacts closed): gaps
          y1 - r and y_{i+1} - y_i - 2r, gravity; at rest from the start (--drop D: each gap opened by D).
  cradle  Newton's cradle: N balls on a line, x_{i+1} - x_i - 2r >= 0, the first moving at v0 toward the
          others; --gap G spaces them (a gapped cradle: one impact at a time), 0 touches them.
  column  a granular column: N balls (coordinates x_i, y_i) in a vertical tube of width W = 3r under
          gravity, dropped in a zigzag (x alternately against the left and the right wall, heights
          r + D + i (sqrt(3) r + D), D from --drop, default 1e-3): a floor under the first ball, both walls
          for every ball, and the nonlinear gap sqrt((x_{i+1} - x_i)^2 + (y_{i+1} - y_i)^2) - 2r between
          neighbours; they land, bounce and settle into the zigzag, every ball on both neighbours and one
          wall (2N closed contacts on 2N coordinates). Why neighbours only: in a tube narrower than 4r the
          order of the balls along it cannot change (W - 2r < 2r), and with W - 2r <= sqrt(3) r two balls
          with one between them are at least 2 sqrt(4r^2 - (W - 2r)^2) >= 2r apart vertically: only
          neighbours touch, and only the first ball reaches the floor.

Masses 1 and radius 0.0625 (a power of two: the positions and gaps are exact binary numbers, so a touching
contact has gap 0.0). The gravity of the stack is a constant potential gradient (potential_gradient), so
the scene's size stays linear in N (a potential written as one sum would exceed the expression length limit).

Usage: scripts/make-contact-scene.py stack|cradle|column N [--e E] [--h H] [--t-end T] [--gap G] [--drop D] [--every K]
"""
import argparse
import json
import math
import sys


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("kind", choices=["stack", "cradle", "column"])
    p.add_argument("n", type=int)
    p.add_argument("--e", type=float, default=None, help="restitution (stack and column 0.5, cradle 1)")
    p.add_argument("--h", type=float, default=1e-3)
    p.add_argument("--t-end", type=float, default=None)
    p.add_argument("--gap", type=float, default=0.0, help="cradle: space between neighbouring balls")
    p.add_argument("--drop", type=float, default=0.0, help="stack, column: opening of each gap at t = 0 (column: default 1e-3)")
    p.add_argument("--every", type=int, default=None, help="/output/every")
    a = p.parse_args()
    n = a.n
    r = 0.0625
    if a.kind == "stack":
        e = 0.5 if a.e is None else a.e
        coords = ["y%d" % (i + 1) for i in range(n)]
        constraints = [{"name": "floor", "gap": "y1 - r", "restitution": "e"}]
        constraints += [{"name": "c%d" % (i + 1), "gap": "y%d - y%d - 2*r" % (i + 1, i), "restitution": "e"} for i in range(1, n)]
        q0 = [r + i * (2 * r + a.drop) + a.drop for i in range(n)]
        scene = {
            "name": "stack-%d" % n,
            "description": "%d balls of mass m and radius r stacked on a floor under gravity%s." % (
                n, "" if a.drop == 0 else ", each gap opened by %g at t = 0" % a.drop),
            "parameters": {"m": 1, "g": 9.81, "r": r, "e": e},
            "units": {"t": "s"},
            "system": {
                "type": "lagrangian",
                "coordinates": coords,
                "mass": {"diagonal": ["m"] * n},
                "potential_gradient": ["m*g"] * n,
                "constraints": constraints,
            },
            "initial": {"q": q0, "v": [0] * n},
            "integrator": {"scheme": "moreau-jean", "h": a.h, "t_end": 1.0 if a.t_end is None else a.t_end},
        }
    elif a.kind == "column":
        e = 0.5 if a.e is None else a.e
        drop = 1e-3 if a.drop == 0.0 else a.drop
        width = 3 * r
        coords = []
        for i in range(n):
            coords += ["x%d" % (i + 1), "y%d" % (i + 1)]
        # Ball by ball (its walls, then its contact with the next): each contact couples only with
        # contacts a few places from it, so the Delassus operator is banded.
        constraints = [{"name": "floor", "gap": "y1 - r", "restitution": "e"}]
        for i in range(1, n + 1):
            constraints.append({"name": "left%d" % i, "gap": "x%d - r" % i, "restitution": "e"})
            constraints.append({"name": "right%d" % i, "gap": "w - r - x%d" % i, "restitution": "e"})
            if i < n:
                constraints.append({"name": "c%d" % i, "gap": "sqrt((x%d - x%d)^2 + (y%d - y%d)^2) - 2*r" % (i + 1, i, i + 1, i),
                                    "restitution": "e"})
        q0 = []
        for i in range(n):
            # The same expressions as bench/siconos/siconos_bench.cc's column: the same bits.
            q0 += [r if i % 2 == 0 else width - r, r + drop + i * (math.sqrt(3.0) * r + drop)]
        scene = {
            "name": "column-%d" % n,
            "description": "A granular column: %d balls of mass m and radius r dropped into a tube of width w under gravity." % n,
            "parameters": {"m": 1, "g": 9.81, "r": r, "w": width, "e": e},
            "units": {"t": "s"},
            "system": {
                "type": "lagrangian",
                "coordinates": coords,
                "mass": {"diagonal": ["m"] * (2 * n)},
                "potential_gradient": ["0", "m*g"] * n,
                "constraints": constraints,
            },
            "initial": {"q": q0, "v": [0] * (2 * n)},
            "integrator": {"scheme": "moreau-jean", "h": a.h, "t_end": 1.0 if a.t_end is None else a.t_end},
        }
    else:
        e = 1.0 if a.e is None else a.e
        coords = ["x%d" % (i + 1) for i in range(n)]
        constraints = [{"name": "c%d" % (i + 1), "gap": "x%d - x%d - 2*r" % (i + 2, i + 1), "restitution": "e"} for i in range(n - 1)]
        q0 = [i * (2 * r + a.gap) for i in range(n)]
        travel = (n - 1) * a.gap  # the wave's path at v0 = 1
        scene = {
            "name": "cradle-%d" % n,
            "description": "Newton's cradle: %d balls of mass m on a line, %s, the first moving at v0." % (
                n, "touching" if a.gap == 0 else "%g apart" % a.gap),
            "parameters": {"m": 1, "r": r, "e": e, "v0": 1},
            "units": {"t": "s"},
            "system": {
                "type": "lagrangian",
                "coordinates": coords,
                "mass": {"diagonal": ["m"] * n},
                "constraints": constraints,
            },
            "initial": {"q": q0, "v": ["v0"] + [0] * (n - 1)},
            "integrator": {"scheme": "moreau-jean", "h": a.h, "t_end": (travel + 0.05) if a.t_end is None else a.t_end},
        }
    if a.every:
        scene["output"] = {"every": a.every}
    json.dump(scene, sys.stdout, indent=1)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
