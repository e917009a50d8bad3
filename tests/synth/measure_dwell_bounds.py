"""Measurements behind docs/complete-query.md §6–7 (not a test: run by hand, ~2 min on 2 cores).

.venv/bin/python tests/synth/measure_dwell_bounds.py [necessity [N [SEED]]|levels|stored|staircase]
"""

import sys


def necessity(count, seed=2026):
    import math

    import numpy as np
    import test_dwell_bounds as T  # this folder is sys.path[0] when the script runs

    rng = np.random.default_rng(seed)
    viol = {"rpr": 0, "rrr": 0}
    n = {"rpr": 0, "rrr": 0}
    else_ = 0
    ratio = {k: {"rpr": [], "rrr": []} for k in (17, 9, 5, 3)}
    swing_viol = 0
    margins = {"rpr": [], "rrr": []}
    for it in range(count):
        b, c, d = rng.uniform(1.5, 5.0, 3)
        if not T.grashof_crank(b, c, d):
            continue
        band = math.radians(rng.choice([0.05, 0.1, 0.3, 1.0]))
        for name, f, bound, smin, tight in T.sixbar_cases(
            float(b), float(c), float(d), int(rng.choice([1, -1])), math.radians(rng.uniform(10, 80)), band, per_kind=3
        ):
            if f.swing < smin - 1e-9:
                swing_viol += 1
            if bound is None:
                else_ += 1
                continue
            n[name] += 1
            a = f.dwells[0].angle
            if a > bound + 1e-9:
                viol[name] += 1
            margins[name].append(math.degrees(bound - a))
            ratio[17][name].append(bound / a)
    print("cases", n, "violations", viol, "swing violations", swing_viol, "longest dwell elsewhere", else_)
    for k in margins:
        if margins[k]:
            m = np.array(margins[k])
            r = np.array(ratio[17][k])
            print(
                k,
                "margin deg min %.2f median %.2f; bound/actual median %.2f p10 %.2f p90 %.2f"
                % (m.min(), np.median(m), np.median(r), np.percentile(r, 10), np.percentile(r, 90)),
            )


def levels():
    import math
    import time

    import numpy as np

    from synth.segment_search.dwell_bounds import curve_extent, deviation_profile, dwell_bound, path_tolerance
    from synth.segment_search.segments import SegmentSearch, find_segments

    rng = np.random.default_rng(7)
    fine = np.logspace(-5, -1, 33)
    prof = []
    cost = {}
    segs = 0
    for it in range(8):
        b, c, d = rng.uniform(1.5, 5.0, 3)
        l = max(b, c, d)
        if 1 + l > b + c + d - l:
            continue
        s = find_segments(np.array([b]), np.array([c]), np.array([d]), np.array([1]), SegmentSearch())
        for i in range(0, len(s), max(1, len(s) // 4)):
            k = 0 if s.kind[i] != 1 else 1
            for step in (1.0, 2.0):
                t = time.perf_counter()
                p = deviation_profile(b, c, d, 1, s.uv[i], s.phi_gen[i], k, levels=fine, step=math.radians(step))
                cost.setdefault(step, []).append(time.perf_counter() - t)
                if step == 1.0:
                    prof.append((k, min(1, b, c, d), p))
            segs += 1
    t = time.perf_counter()
    curve_extent(2.5, 3.0, 3.0, 1, 0.5 + 0.5j)
    ce = time.perf_counter() - t
    print(
        "segments",
        segs,
        "profile cost s/segment:",
        {k: round(float(np.median(v)), 3) for k, v in cost.items()},
        "curve_extent s:",
        round(ce, 4),
    )
    for K, sub in (
        (33, slice(None)),
        (17, slice(None, None, 2)),
        (9, slice(None, None, 4)),
        (5, slice(None, None, 8)),
        (3, slice(None, None, 16)),
    ):
        rs = []
        for k, m4, p in prof:
            for beta in (0.05, 0.1, 0.3, 1.0):
                for ratio in (3, 10, 20):
                    e = path_tolerance("rpr" if k == 0 else "rrr", math.radians(beta), ratio, m4)
                    ref = dwell_bound(fine, p.length, e)
                    got = dwell_bound(fine[sub], p.length[sub], e)
                    if ref < 2 * math.pi and got < 2 * math.pi:
                        rs.append(got / ref)
        rs = np.array(rs)
        print(
            f"levels {K}: bound / bound(33 levels) median {np.median(rs):.3f} p90 {np.percentile(rs, 90):.3f} max {rs.max():.3f} (n={rs.size})"
        )


def stored():
    import math
    import time

    import numpy as np

    from synth.segment_search.dwell_bounds import deviation_profile
    from synth.segment_search.segments import SegmentSearch, find_segments

    rng = np.random.default_rng(11)
    B = []
    while len(B) < 40:
        b, c, d = rng.uniform(1.5, 5.0, 3)
        l = max(b, c, d)
        if 1 + l <= b + c + d - l:
            B.append((b, c, d))
    b, c, d = (np.array(x) for x in zip(*B))
    br = np.ones(len(B), int)
    lv9 = tuple(float(x) for x in np.logspace(-5, -1, 9))
    for tols in ((1e-4, 1e-3, 1e-2), lv9):
        t = time.perf_counter()
        s = find_segments(b, c, d, br, SegmentSearch(tolerances=tols))
        dt = time.perf_counter() - t
        print(
            len(tols),
            "levels:",
            len(s),
            "segments",
            round(dt, 2),
            "s",
            round(1e3 * dt / max(len(s), 1), 2),
            "ms/segment",
        )
    r = []
    for i in range(0, len(s), max(1, len(s) // 25)):
        if s.kind[i] == 2:
            continue
        L = s.linkage[i]
        p = deviation_profile(
            b[L], c[L], d[L], 1, s.uv[i], s.phi_gen[i], int(s.kind[i]), levels=lv9, step=math.radians(1.0)
        )
        stored = s.phi_end[i, :, 0] - s.phi_start[i, :, 0]
        ok = s.has_dwell[i, :, 0]
        for k in np.flatnonzero(ok):
            r.append((int(s.kind[i]), p.length[k] / stored[k], math.degrees(p.length[k] - stored[k])))
    r = np.array(r)
    for k in (0, 1):
        x = r[r[:, 0] == k]
        if x.size:
            print(
                "kind",
                k,
                "n",
                len(x),
                "exact profile / stored dwell: min %.3f median %.3f max %.3f; difference deg median %.1f max %.1f"
                % (x[:, 1].min(), np.median(x[:, 1]), x[:, 1].max(), np.median(x[:, 2]), x[:, 2].max()),
            )


def staircase(count=20):
    """Cost per segment of the batched staircase profile (9 levels) on every segment of
    ``count`` random linkages, per kind, at 1° and 2°."""
    import math
    import time

    import numpy as np

    from synth.segment_search.dwell_bounds import deviation_profiles
    from synth.segment_search.segments import SegmentSearch, find_segments

    rng = np.random.default_rng(5)
    B = []
    while len(B) < count:
        b, c, d = rng.uniform(1.5, 5.0, 3)
        l = max(b, c, d)
        if 1 + l <= b + c + d - l:
            B.append((b, c, d))
    b, c, d = (np.array(x) for x in zip(*B))
    br = np.ones(count, int)
    s = find_segments(b, c, d, br, SegmentSearch())
    for kind in (0, 1):
        rows = np.flatnonzero(s.kind == kind)
        L = s.linkage[rows]
        for step in (1.0, 2.0):
            t = time.perf_counter()
            deviation_profiles(
                b[L],
                c[L],
                d[L],
                br[L],
                s.uv[rows],
                s.phi_gen[rows],
                kind,
                levels=np.logspace(-5, -1, 9),
                step=math.radians(step),
            )
            dt = time.perf_counter() - t
            print(f"kind {kind}: {rows.size} segments, step {step}°: {1e3 * dt / max(rows.size, 1):.1f} ms/segment")


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "necessity"
    if what == "necessity":
        necessity(int(sys.argv[2]) if len(sys.argv) > 2 else 40, int(sys.argv[3]) if len(sys.argv) > 3 else 2026)
    elif what == "levels":
        levels()
    elif what == "staircase":
        staircase()
    else:
        stored()
