#!/usr/bin/env python3
"""Side-by-side comparison of Moreau and Siconos 4.4 (docs/siconos-comparison.md; the contact rows at scale:
docs/scaling.md).

For each row it runs both sides in turn:
  - Moreau: the Google Benchmark binaries (build/bench/core_bench, build/bench/second_paper_bench) with
    --benchmark_filter for the matching benchmark (median ns_per_step over --reps repetitions), or, for a
    configuration no benchmark runs, `moreau run SCENE --json` (median over --reps processes of the
    report's integrate phase / steps); then `moreau run SCENE --out` for the trajectory;
  - Siconos: bench/siconos's siconos_bench (median ns/step of the stepping loop over --reps runs, and a
    trajectory with --csv).
Each side's time is the smallest of --rounds round medians, the rounds alternating the two sides.
Both trajectories are scored by this script with the same code against the same reference: the closed
form where one exists (bouncing ball, damped relay, two-state relay Lur'e system), otherwise a fine-h run
of each side (the manipulator: each side against its own fine run; the distance between the two fine
runs is printed too).

The ratio is also given at equal accuracy: the side whose position error is the larger at the same h is
rerun at the h that brings it down to the other side's, and charged for the extra steps. Moreau is charged
at its ns/step at h (its benchmarks run that h); Siconos is timed at its smaller h in the same rounds.

Usage:
  scripts/compare-siconos.py [--moreau-build build] [--siconos /tmp/siconos-build/siconos_bench]
                             [--reps 7] [--rounds 5] [--rows manipulator,ball,...] [--json out.json] [--markdown]
"""
import argparse
import bisect
import csv
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# A row: one workload at one (h, t_end). 'bench' and 'compiled' name the Moreau benchmarks that run exactly
# this configuration (scene benchmark, compiled C++ model); None means `moreau run` times it instead.
ROWS = [
    dict(id="manipulator", scene="manipulator.json", siconos="manipulator", h=1e-3, t_end=10.0,
         bench=("core_bench", "BM_ManipulatorJsonScene_to_rest"),
         compiled=("core_bench", "BM_ManipulatorCompiled_to_rest"), score="manipulator"),
    dict(id="ball", scene="bouncing-ball-e0.5.json", siconos="ball", h=1e-3, t_end=3.0,
         bench=("second_paper_bench", "BM_BouncingBallJsonScene_to_rest"),
         compiled=("second_paper_bench", "BM_BouncingBallCompiled_to_rest"), score="ball"),
    dict(id="damped-relay", scene="damped-relay.json", siconos="damped-relay", h=1e-3, t_end=6.0,
         bench=None, compiled=None, score="damped-relay"),
    dict(id="lure-relay", scene="lure-relay-2state.json", siconos="lure-relay", h=1e-3, t_end=10.0,
         bench=("second_paper_bench", "BM_RelayLure2JsonScene_sliding"),
         compiled=("second_paper_bench", "BM_RelayLure2Compiled_sliding"), score="lure"),
    # The same workloads stopped while everything still moves (every step does the full work), at the
    # configurations of Moreau's "moving" benchmarks.
    dict(id="manipulator-moving", scene="manipulator.json", siconos="manipulator", h=1e-3, t_end=1.0,
         bench=("core_bench", "BM_ManipulatorJsonScene_moving"),
         compiled=("core_bench", "BM_ManipulatorCompiled_moving"), score="manipulator"),
    dict(id="ball-moving", scene="bouncing-ball-e0.5.json", siconos="ball", h=1e-3, t_end=1.3,
         bench=("second_paper_bench", "BM_BouncingBallJsonScene_moving"),
         compiled=("second_paper_bench", "BM_BouncingBallCompiled_moving"), score="ball"),
    dict(id="damped-relay-moving", scene="damped-relay.json", siconos="damped-relay", h=1e-4, t_end=3.6,
         bench=("core_bench", "BM_DampedRelayJsonScene_moving"),
         compiled=("core_bench", "BM_DampedRelayCompiled_moving"), score="damped-relay"),
    dict(id="lure-relay-moving", scene="lure-relay-2state.json", siconos="lure-relay", h=1e-3, t_end=0.2,
         bench=("second_paper_bench", "BM_RelayLure2JsonScene_moving"),
         compiled=("second_paper_bench", "BM_RelayLure2Compiled_moving"), score="lure"),
    # The manipulator and the damped relay on Moreau's moreau-jean scheme, the discrete scheme of Siconos'
    # MoreauJeanOSI for the relay (the same velocity recurrence as (0.2), the position moved with V^{k+1}).
    dict(id="manipulator-mj", scene="manipulator.json", scheme="moreau-jean", siconos="manipulator", h=1e-3,
         t_end=10.0, bench=("second_paper_bench", "BM_ManipulatorMoreauJeanJsonScene_to_rest"), compiled=None,
         score="manipulator"),
    dict(id="manipulator-mj-moving", scene="manipulator.json", scheme="moreau-jean", siconos="manipulator",
         h=1e-3, t_end=1.0, bench=("second_paper_bench", "BM_ManipulatorMoreauJeanJsonScene_moving"),
         compiled=None, score="manipulator"),
    dict(id="damped-relay-mj", scene="damped-relay.json", scheme="moreau-jean", siconos="damped-relay", h=1e-3,
         t_end=6.0, bench=("second_paper_bench", "BM_DampedRelayMoreauJeanJsonScene_to_rest"), compiled=None,
         score="damped-relay"),
    dict(id="damped-relay-mj-moving", scene="damped-relay.json", scheme="moreau-jean", siconos="damped-relay",
         h=1e-4, t_end=3.6, bench=("second_paper_bench", "BM_DampedRelayMoreauJeanJsonScene_moving"),
         compiled=None, score="damped-relay"),
    # Contact systems at scale (docs/scaling.md): the stack of N balls at rest on a floor, and the gapped
    # Newton's cradle (1 cm apart, e = 1, the first ball at 1 m/s), scenes written by
    # scripts/make-contact-scene.py; Moreau runs them on its large-contact path. Scored against their exact
    # answers (the stack does not move; the cradle ends at (0, ..., 0, 1)); Moreau meets both exactly, so
    # no equal-accuracy rerun: the ratio is at the same h, with each side's error shown.
    *[dict(id=f"stack-{n}", contact=("stack", n), siconos="stack", h=1e-3, t_end=1.0, bench=None, compiled=None,
           score="stack") for n in (8, 64, 128)],
    # The cradle runs until the wave has crossed it ((N - 1) gaps at 1 m/s), then 50 steps.
    *[dict(id=f"cradle-{n}", contact=("cradle", n), siconos="cradle", h=1e-3, t_end=round(0.01 * (n - 1) + 0.05, 6),
           bench=None, compiled=None, score="cradle") for n in (8, 64, 256)],
    # The granular column: N balls dropped 1 mm apart into a tube of width 3r (nonlinear gaps between
    # balls), landing and settling over 1 s. No exact answer: scored by the deepest penetration of any
    # contact over the run (both sides are velocity-level Moreau-Jean schemes without position correction)
    # and the final speed; the side that penetrates deeper is rerun at the h that matches the other.
    *[dict(id=f"column-{n}", contact=("column", n), siconos="column", h=1e-3, t_end=1.0, bench=None, compiled=None,
           score="column") for n in (8, 64)],
]

# The column's geometry (scripts/make-contact-scene.py column): radius and tube width.
COLUMN_R = 0.0625
COLUMN_W = 3 * COLUMN_R

# Samples with |v| <= this are "at rest" when a rest time is read off a trajectory (Moreau's are 0.0
# exactly; Siconos' can carry round-off).
REST_TOL = 1e-12


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode not in (0,):
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-2000:]}")
    return r.stdout


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    cols = {name: [float(r[i]) for r in rows[1:]] for i, name in enumerate(header)}
    return cols


# ---- exact solutions ---------------------------------------------------------------------------------
def ball_exact(t, y0=1.0, g=9.81, e=0.5):
    """Height of the ball dropped from y0 at rest, Newton restitution e (scenes/bouncing-ball-e0.5.json)."""
    t1 = math.sqrt(2 * y0 / g)
    t_inf = t1 * (1 + e) / (1 - e)
    if t <= t1:
        return y0 - 0.5 * g * t * t
    if t >= t_inf:
        return 0.0
    tk, u = t1, e * g * t1
    while True:
        dur = 2 * u / g
        if t <= tk + dur or dur < 1e-300:
            s = t - tk
            return u * s - 0.5 * g * s * s
        tk += dur
        u *= e


def ball_rest_time(y0=1.0, g=9.81, e=0.5):
    return math.sqrt(2 * y0 / g) * (1 + e) / (1 - e)


DR = dict(m=2.0, c=0.5, a=1.0, q0=0.0, v0=3.0)
DR_T_STOP = DR["m"] / DR["c"] * math.log(1 + DR["c"] * DR["v0"] / DR["a"])


def damped_relay_exact(t):
    """m x'' = -c x' - a Sign(x') (scenes/damped-relay.json's /exact)."""
    m, c, a, q0, v0 = DR["m"], DR["c"], DR["a"], DR["q0"], DR["v0"]
    ts = min(t, DR_T_STOP)
    q = q0 + m / c * (v0 + a / c) * (1 - math.exp(-c * ts / m)) - a / c * ts
    v = max(0.0, (v0 + a / c) * math.exp(-c * t / m) - a / c)
    return q, v


# Two-state relay x' = A x - B Sign(C x), A = [[0, 1], [-2, -3]], B = (0, 1), C = (1, 2), x(0) = (1, 0).
# Until y = C x reaches 0, w = 1 and x = x* + e^{At}(x0 - x*), x* = A^{-1} B = (-1/2, 0):
#   x1 = -1/2 + 3/2 (2 e^-t - e^-2t),  x2 = 3 (e^-2t - e^-t),  y = -1/2 + 3/2 (3 e^-2t - 2 e^-t),
# which first vanishes at u = e^-t1 = (1 + sqrt 2)/3 (9u^2 - 6u - 1 = 0), t1 = 0.2172...; there
# x2 = -sqrt(2)/3. Then the solution slides on y = 0: w = C A x / C B = 3/2 x2 (|w| = 0.71 <= 1, decreasing)
# and x2' = -x2/2, x1 = -2 x2.
LURE_T1 = -math.log((1 + math.sqrt(2)) / 3)


def lure_exact(t):
    if t <= LURE_T1:
        a, b = math.exp(-t), math.exp(-2 * t)
        return -0.5 + 1.5 * (2 * a - b), 3 * (b - a)
    x2 = -math.sqrt(2) / 3 * math.exp(-0.5 * (t - LURE_T1))
    return -2 * x2, x2


def rest_time(ts, vs_list):
    """First sample time from which every velocity stays within REST_TOL to the end (None if never)."""
    k = len(ts)
    while k > 0 and all(abs(vs[k - 1]) <= REST_TOL for vs in vs_list):
        k -= 1
    return ts[k] if k < len(ts) else None


def score(kind, cols, ref=None):
    """Errors of one trajectory; cols maps column names to lists. Returns a dict."""
    t = cols["t"]
    if kind == "ball":
        err = max(abs(y - ball_exact(tt)) for tt, y in zip(t, cols["y"]))
        out = dict(max_err_y=err, min_gap=min(cols["y"]))
        tr = rest_time(t, [cols["y_dot"]])
        tinf = ball_rest_time()
        if t[-1] > tinf:
            out["rest_time"] = tr
            out["rest_time_err"] = None if tr is None else abs(tr - tinf)
        return out
    if kind == "damped-relay":
        eq = max(abs(q - damped_relay_exact(tt)[0]) for tt, q in zip(t, cols["x"]))
        ev = max(abs(v - damped_relay_exact(tt)[1]) for tt, v in zip(t, cols["x_dot"]))
        out = dict(max_err_q=eq, max_err_v=ev)
        if t[-1] > DR_T_STOP:
            tr = rest_time(t, [cols["x_dot"]])
            out["rest_time"] = tr
            out["rest_time_err"] = None if tr is None else abs(tr - DR_T_STOP)
        return out
    if kind == "lure":
        err = 0.0
        for tt, x1, x2 in zip(t, cols["x1"], cols["x2"]):
            e1, e2 = lure_exact(tt)
            err = max(err, abs(x1 - e1), abs(x2 - e2))
        return dict(max_err_x=err)
    if kind == "manipulator":
        return dict(max_err_q=trajectory_distance(cols, ref, ("x1", "th2")))
    if kind == "stack":
        # At rest from the start: every position stays at its initial value, every velocity 0.
        ys = [name for name in cols if name.startswith("y") and not name.endswith("_dot")]
        sink = max(abs(y - cols[n][0]) for n in ys for y in cols[n])
        speed = max(abs(v) for n in ys for v in cols[n + "_dot"])
        return dict(max_sink=sink, max_speed=speed)
    if kind == "cradle":
        # e = 1, equal masses: the wave hands the velocity on exactly; the end state is (0, ..., 0, 1).
        xs = [name for name in cols if name.startswith("x") and not name.endswith("_dot")]
        final = [cols[n + "_dot"][-1] for n in xs]
        exact = [0.0] * (len(xs) - 1) + [1.0]
        return dict(final_v_err=max(abs(v - e) for v, e in zip(final, exact)))
    if kind == "column":
        # Every contact's gap at every sample: the floor under ball 1, both walls, neighbours' distance - 2r.
        n = sum(1 for name in cols if name.startswith("x") and not name.endswith("_dot"))
        x = [cols[f"x{i + 1}"] for i in range(n)]
        y = [cols[f"y{i + 1}"] for i in range(n)]
        deepest = min(y[0]) - COLUMN_R
        for i in range(n):
            deepest = min(deepest, min(x[i]) - COLUMN_R, COLUMN_W - COLUMN_R - max(x[i]))
            if i + 1 < n:
                deepest = min(deepest, min(math.hypot(a - b, c - d) for a, b, c, d in zip(x[i + 1], x[i], y[i + 1], y[i])) - 2 * COLUMN_R)
        speed = max(abs(cols[name][-1]) for name in cols if name.endswith("_dot"))
        return dict(max_penetration=max(0.0, -deepest), final_speed=speed)
    raise ValueError(kind)


def trajectory_distance(a, ref, names):
    """max over the reference's sample times within a's span of max_i |a_i(t) - ref_i(t)|, a interpolated
    linearly between its samples (exact where a has a sample at t, as when both run on the 1e-3 grid)."""
    ta = a["t"]
    worst = 0.0
    for k, t in enumerate(ref["t"]):
        if t < ta[0] - 1e-12 or t > ta[-1] + 1e-12:
            continue
        j = bisect.bisect_left(ta, t - 1e-12)
        j = min(j, len(ta) - 1)
        if abs(ta[j] - t) <= 1e-9 * max(1.0, t) or j == 0:
            vals = [a[n][j] for n in names]
        else:
            w = (t - ta[j - 1]) / (ta[j] - ta[j - 1])
            vals = [a[n][j - 1] + w * (a[n][j] - a[n][j - 1]) for n in names]
        worst = max(worst, max(abs(v - ref[n][k]) for v, n in zip(vals, names)))
    return worst


# ---- the two sides ------------------------------------------------------------------------------------
def moreau_bench(binary, name, reps):
    out = run([binary, f"--benchmark_filter=^{name}$", f"--benchmark_repetitions={reps}",
               "--benchmark_report_aggregates_only=true", "--benchmark_format=json"])
    for b in json.loads(out)["benchmarks"]:
        if b.get("aggregate_name") == "median":
            # The counter is a rate inverted (kIsRate | kInvert): seconds per step in the JSON output.
            return b["ns_per_step"] * 1e9
    raise RuntimeError(f"{name}: no median in the benchmark output")


def moreau_sets(row):
    sets = ["--set", f"integrator.h={row['h']!r}", "--set", f"integrator.t_end={row['t_end']!r}"]
    if "scheme" in row:
        sets += ["--set", f"integrator.scheme={row['scheme']}"]
    return sets


def scene_path(row):
    """The row's scene file: from scenes/, or written by scripts/make-contact-scene.py (row["contact"])."""
    return row.get("path") or os.path.join(ROOT, "scenes", row["scene"])


def siconos_extra(row):
    """siconos_bench's arguments for the row's size (the contact workloads)."""
    if "contact" not in row:
        return []
    kind, n = row["contact"]
    return ["--n", str(n)] + (["--gap", "0.01"] if kind == "cradle" else [])


def moreau_run_timing(cli, row, reps):
    """Median over reps processes of the report's integrate phase per step (plus one warm-up)."""
    vals = []
    for i in range(reps + 1):
        rep = json.loads(run([cli, "run", scene_path(row), "--json"] + moreau_sets(row)))
        steps = rep["steps"]
        if i:
            vals.append(rep["phase_seconds"]["integrate"] * 1e9 / steps)
    return statistics.median(vals)


def moreau_trajectory(cli, row, path, h=None, every=1):
    sets = moreau_sets(row)
    if h is not None:
        sets = ["--set", f"integrator.h={h!r}", "--set", f"integrator.t_end={row['t_end']!r}",
                "--set", f"output.every={every}"]
        if "scheme" in row:
            sets += ["--set", f"integrator.scheme={row['scheme']}"]
    run([cli, "run", scene_path(row), "--out", path, "--json"] + sets)
    return read_csv(path)


def siconos_run(binary, row, reps, csv_path=None, h=None, every=1, extra=()):
    cmd = [binary, row["siconos"], "--h", repr(h if h is not None else row["h"]), "--t-end", repr(row["t_end"]),
           "--reps", str(reps)] + siconos_extra(row) + list(extra)
    if csv_path:
        cmd += ["--csv", csv_path, "--every", str(every)]
    return json.loads(run(cmd).strip().splitlines()[-1])


def fmt(x, digits=3):
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-2:
        return f"{x:.{digits - 1}e}"
    return f"{x:.{digits}g}"


def headline_error(kind, s):
    """The one number equal accuracy is judged on: the position error over the run."""
    return {"ball": "max_err_y", "damped-relay": "max_err_q", "lure": "max_err_x", "manipulator": "max_err_q",
            "stack": "max_sink", "cradle": "final_v_err", "column": "max_penetration"}[kind]


def headline(kind, s):
    if kind == "ball":
        r = f"y {fmt(s['max_err_y'])}"
        if "rest_time_err" in s:
            r += f"; rest {fmt(s['rest_time_err'])}"
        return r + f"; min y {fmt(s['min_gap'])}"
    if kind == "damped-relay":
        r = f"q {fmt(s['max_err_q'])}, v {fmt(s['max_err_v'])}"
        if "rest_time_err" in s:
            r += f"; rest {fmt(s['rest_time_err'])}"
        return r
    if kind == "lure":
        return f"x {fmt(s['max_err_x'])}"
    if kind == "stack":
        return f"sink {fmt(s['max_sink'])}, |v| {fmt(s['max_speed'])}"
    if kind == "cradle":
        return f"final v {fmt(s['final_v_err'])}"
    if kind == "column":
        return f"penetration {fmt(s['max_penetration'])}, final |v| {fmt(s['final_speed'])}"
    return f"q {fmt(s['max_err_q'])}"


def equal_accuracy_h(row, target, error_at, whole_steps):
    """The largest h tried (from h * target / error downwards, first order) at which a side's headline
    error, error_at(h, attempt), is at most target, with that error; each guess is checked by a run.
    whole_steps: h divides t_end into whole steps (rounded down from the guess), for Siconos, whose
    TimeStepping aborts on a last step shorter than h (an assertion that t_{k+1} is a number)."""
    h = row["h"]
    err = None
    for attempt in range(6):
        if whole_steps:
            h = row["t_end"] / math.ceil(row["t_end"] / h - 1e-9)
        err = error_at(h, attempt)
        if err <= target:
            return h, err
        h *= 0.98 * target / err
    return h, err


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--moreau-build", default=os.path.join(ROOT, "build"),
                    help="Moreau build directory (bench/core_bench, bench/second_paper_bench, client/moreau)")
    ap.add_argument("--core-bench", help="path of core_bench (default: MOREAU_BUILD/bench/core_bench)")
    ap.add_argument("--second-paper-bench", help="path of second_paper_bench (default: MOREAU_BUILD/bench/...)")
    ap.add_argument("--moreau", help="path of the moreau command (default: MOREAU_BUILD/client/moreau)")
    ap.add_argument("--siconos", default="/tmp/siconos-build/siconos_bench", help="path of siconos_bench")
    ap.add_argument("--reps", type=int, default=7, help="timed repetitions on each side in a round (median)")
    ap.add_argument("--rounds", type=int, default=5,
                    help="rounds, alternating the sides; each side's time is its smallest round median "
                         "(a busy machine only ever slows a round)")
    ap.add_argument("--rows", default=",".join(r["id"] for r in ROWS), help="comma-separated row ids")
    ap.add_argument("--moreau-ref-h", type=float, default=1e-6, help="h of Moreau's manipulator reference")
    ap.add_argument("--siconos-ref-h", type=float, default=1e-5, help="h of Siconos' manipulator reference")
    ap.add_argument("--siconos-args", default="", help="extra arguments for siconos_bench (e.g. '--solver pgs')")
    ap.add_argument("--json", help="write every number to this file")
    ap.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    ap.add_argument("--keep", action="store_true", help="keep the trajectories (CSV) in the temporary directory")
    args = ap.parse_args()

    bins = {
        "core_bench": args.core_bench or os.path.join(args.moreau_build, "bench", "core_bench"),
        "second_paper_bench": args.second_paper_bench or os.path.join(args.moreau_build, "bench", "second_paper_bench"),
    }
    cli = args.moreau or os.path.join(args.moreau_build, "client", "moreau")
    for p in list(bins.values()) + [cli, args.siconos]:
        if not os.access(p, os.X_OK):
            sys.exit(f"compare-siconos: {p} is not an executable (see --help for the path options)")
    extra = args.siconos_args.split()
    wanted = args.rows.split(",")
    unknown = set(wanted) - {r["id"] for r in ROWS}
    if unknown:
        sys.exit(f"compare-siconos: unknown rows {sorted(unknown)}")
    rows = [r for r in ROWS if r["id"] in wanted]
    tmp = tempfile.mkdtemp(prefix="compare-siconos-")
    results = []

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    refs = {}
    if any(r["score"] == "manipulator" for r in rows):
        base = next(r for r in ROWS if r["id"] == "manipulator")
        log(f"references: Moreau manipulator at h = {args.moreau_ref_h:g}, Siconos at h = {args.siconos_ref_h:g}")
        refs["moreau"] = moreau_trajectory(cli, base, os.path.join(tmp, "moreau-ref.csv"), h=args.moreau_ref_h,
                                           every=max(1, round(1e-3 / args.moreau_ref_h)))
        siconos_run(args.siconos, base, 0, os.path.join(tmp, "siconos-ref.csv"), h=args.siconos_ref_h,
                    every=max(1, round(1e-3 / args.siconos_ref_h)), extra=extra)
        refs["siconos"] = read_csv(os.path.join(tmp, "siconos-ref.csv"))
        refs["distance"] = trajectory_distance(refs["moreau"], refs["siconos"], ("x1", "th2"))

    for row in rows:
        if "contact" in row:
            kind_n = row["contact"]
            row["path"] = os.path.join(tmp, f"{row['id']}.json")
            extra_args = ["--gap", "0.01"] if kind_n[0] == "cradle" else []
            with open(row["path"], "w") as f:
                f.write(run([sys.executable, os.path.join(ROOT, "scripts", "make-contact-scene.py"), kind_n[0], str(kind_n[1]),
                             "--h", repr(row["h"]), "--t-end", repr(row["t_end"])] + extra_args))
        # Accuracy first (untimed), then the timed rounds.
        log(f"{row['id']}: trajectories")
        m_cols = moreau_trajectory(cli, row, os.path.join(tmp, f"moreau-{row['id']}.csv"))
        s_info = siconos_run(args.siconos, row, 0, os.path.join(tmp, f"siconos-{row['id']}.csv"), extra=extra)
        s_cols = read_csv(os.path.join(tmp, f"siconos-{row['id']}.csv"))
        kind = row["score"]
        if kind == "manipulator":
            m_err = score(kind, m_cols, refs["moreau"])
            s_err = score(kind, s_cols, refs["siconos"])
            m_err["vs_other_ref"] = trajectory_distance(m_cols, refs["siconos"], ("x1", "th2"))
            s_err["vs_other_ref"] = trajectory_distance(s_cols, refs["moreau"], ("x1", "th2"))
        else:
            m_err = score(kind, m_cols)
            s_err = score(kind, s_cols)
        key = headline_error(kind, m_err)
        # Equal accuracy: the side with the larger error at the same h is run at the smaller h that brings
        # its error down to the other's, and charged for the extra steps.
        h_eq, e_eq = row["h"], m_err[key]
        s_h_eq, s_e_eq = row["h"], s_err[key]

        def moreau_error_at(h, attempt):
            path = os.path.join(tmp, f"moreau-{row['id']}-eq{attempt}.csv")
            return score(kind, moreau_trajectory(cli, row, path, h=h, every=1), refs.get("moreau"))[key]

        def siconos_error_at(h, attempt):
            path = os.path.join(tmp, f"siconos-{row['id']}-eq{attempt}.csv")
            siconos_run(args.siconos, row, 0, path, h=h, extra=extra)
            return score(kind, read_csv(path), refs.get("siconos"))[key]

        if kind in ("stack", "cradle"):
            pass  # exact answers: Moreau's error is 0 (checked below in the table), no rerun
        elif m_err[key] > s_err[key]:
            log(f"{row['id']}: Moreau at equal accuracy")
            h_eq, e_eq = equal_accuracy_h(row, s_err[key], moreau_error_at, whole_steps=False)
        elif s_err[key] > m_err[key]:
            log(f"{row['id']}: Siconos at equal accuracy")
            s_h_eq, s_e_eq = equal_accuracy_h(row, m_err[key], siconos_error_at, whole_steps=True)

        m_runs, c_runs, s_runs, s_eq_runs = [], [], [], []
        for rnd in range(args.rounds):
            log(f"{row['id']}: timing, round {rnd + 1}/{args.rounds}")
            if row["bench"]:
                m_runs.append(moreau_bench(bins[row["bench"][0]], row["bench"][1], args.reps))
            else:
                m_runs.append(moreau_run_timing(cli, row, args.reps))
            if row["compiled"]:
                c_runs.append(moreau_bench(bins[row["compiled"][0]], row["compiled"][1], args.reps))
            s_runs.append(siconos_run(args.siconos, row, args.reps, extra=extra)["ns_per_step"])
            if s_h_eq != row["h"]:
                s_eq_runs.append(siconos_run(args.siconos, row, args.reps, h=s_h_eq, extra=extra)["ns_per_step"])
        m_ns, s_ns = min(m_runs), min(s_runs)
        s_eq_ns = min(s_eq_runs) if s_eq_runs else s_ns
        m_comp = min(c_runs) if c_runs else None
        results.append(dict(
            row=row["id"], scene=row.get("scene", " ".join(map(str, row.get("contact", ())))), h=row["h"], t_end=row["t_end"],
            moreau_ns=m_ns, moreau_rounds=m_runs,
            moreau_source=row["bench"][1] if row["bench"] else "moreau run --json: phase_seconds.integrate / steps",
            moreau_compiled_ns=m_comp, moreau_compiled_rounds=c_runs,
            siconos_ns=s_ns, siconos_rounds=s_runs, siconos=s_info,
            ratio=s_ns / m_ns, ratio_compiled=(s_ns / m_comp) if m_comp else None,
            moreau_error=m_err, siconos_error=s_err, score=kind, headline=key,
            moreau_h_equal_accuracy=h_eq, moreau_error_equal_accuracy=e_eq,
            siconos_h_equal_accuracy=s_h_eq, siconos_error_equal_accuracy=s_e_eq,
            siconos_ns_equal_accuracy=s_eq_ns, siconos_rounds_equal_accuracy=s_eq_runs,
            # Same horizon: a run costs ns/step * t_end / h on each side, each at its equal-accuracy h.
            ratio_equal_accuracy=(s_eq_ns * row["t_end"] / s_h_eq) / (m_ns * row["t_end"] / h_eq)))

    head = ["workload", "h", "t_end", "Moreau ns/step (scene)", "Moreau ns/step (compiled)", "Siconos ns/step",
            "Siconos/Moreau", "at equal accuracy", "Moreau error", "Siconos error"]
    lines = []
    for r in results:
        eq = f"{r['ratio_equal_accuracy']:.0f}x"
        if r["score"] in ("stack", "cradle"):
            eq = "-" if r["moreau_error"][r["headline"]] != 0.0 else "(Moreau exact; same h)"
        if r["moreau_h_equal_accuracy"] != r["h"]:
            eq += f" (Moreau h {r['moreau_h_equal_accuracy']:.3g})"
        if r["siconos_h_equal_accuracy"] != r["h"]:
            eq += (f" (Siconos h {r['siconos_h_equal_accuracy']:.3g}: {fmt(r['siconos_ns_equal_accuracy'])} ns/step, "
                   f"error {fmt(r['siconos_error_equal_accuracy'])})")
        lines.append([r["row"], f"{r['h']:g}", f"{r['t_end']:g}", fmt(r["moreau_ns"]), fmt(r["moreau_compiled_ns"]),
                      fmt(r["siconos_ns"]),
                      f"{r['ratio']:.0f}x" + (f" ({r['ratio_compiled']:.0f}x compiled)" if r["ratio_compiled"] else ""),
                      eq, headline(r["score"], r["moreau_error"]), headline(r["score"], r["siconos_error"])])
    if args.markdown:
        print("| " + " | ".join(head) + " |")
        print("|" + "---|" * len(head))
        for l in lines:
            print("| " + " | ".join(l) + " |")
    else:
        widths = [max(len(h), *(len(l[i]) for l in lines)) for i, h in enumerate(head)]
        print("  ".join(h.ljust(w) for h, w in zip(head, widths)))
        for l in lines:
            print("  ".join(c.ljust(w) for c, w in zip(l, widths)))
    print()
    print("errors: max over the run's samples; ball y and damped relay q, v against the closed form, rest = |rest time - "
          "exact|, min y = deepest penetration; Lur'e x against the closed form; manipulator q against each side's own "
          "fine run; stack: the largest sink of a ball and speed (exact: 0, 0); cradle: the final velocities against "
          "(0, ..., 0, 1). 'at equal accuracy': the side whose position error is the larger is rerun at the h that "
          "matches the other's (shown) and charged for the extra steps: Moreau at its ns/step at h, Siconos at its "
          "ns/step timed at that h in the same rounds.")
    if refs:
        print(f"manipulator references: Moreau h = {args.moreau_ref_h:g}, Siconos h = {args.siconos_ref_h:g}; they differ "
              f"by {fmt(refs['distance'])} (max |q|).")
        for r in results:
            if r["score"] == "manipulator":
                print(f"  {r['row']}: errors against the other side's reference: Moreau "
                      f"{fmt(r['moreau_error']['vs_other_ref'])}, Siconos {fmt(r['siconos_error']['vs_other_ref'])}")
    la = os.getloadavg()
    print(f"timing: {args.rounds} rounds x median of {args.reps} (Moreau: Google Benchmark repetitions, or moreau run "
          f"processes for damped-relay and the contact rows; Siconos: the stepping loop after a warm-up run), smallest round median kept. "
          f"Load average at the end {la[0]:.2f} {la[1]:.2f} {la[2]:.2f}, {os.cpu_count()} cores.")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(dict(rows=results, reference_distance=refs.get("distance"), reps=args.reps, rounds=args.rounds,
                           loadavg=la), f, indent=1)
    if args.keep:
        print(f"trajectories kept in {tmp}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
