"""RRR double dwells from two equal arcs of a general coupler curve (docs/query-double-dwell.md,
section "RRR double dwells from two equal arcs"): does the 4-D family of four-bars whose coupler
curve has two vertices of the same radius hold six-bars with two separated rests of d ± 5° at a
swing of 20° or 45°, within the default limits?

An RRR output rests twice if its moving pivot Q sits at the centre C1 of one near-circular
stretch of the coupler path while P runs on it, and at the centre C2 of another while P runs on
that one: the rod ρ is both stretches' radius, the rocker pivot D lies on the perpendicular
bisector of C1C2 (rocker L = |DC1| = |DC2|), the swing between the rests is the angle C1–D–C2,
and the dyad's branch, the sign of Im(conj(D − P)·(Q − P)), must be the same at both (a mirror
pair of arcs fails exactly this: measure_symmetric_double.py).

1. The source: the `standard` atlas's four-bars (read-only: b, c, d of branch +1 with the
   four-bar's transmission angle in [30°, 150°]; branch −1 is the mirror image about the ground
   line and the coupler-point grid covers both sides), every ``STRIDE``-th (all; ``--quick``: every
   40th), and coupler points on
   a grid in the coupler frame scaled by b, the plate's link ratio ≤ 10
   (:func:`synth.mechanism.link_ratio.segment_link_ratio`).
2. The vertices of each coupler curve: the crank angles where the path's radius of curvature
   (Euler–Savary, :func:`synth.curvature.inflection.euler_savary`, every 0.5°) is stationary,
   radius 0.2–8 cranks (``stationary_arcs`` of measure_symmetric_double.py).
3. Pairs of vertices of one curve, radii within ``PAIR_RADIUS`` of their mean, centres ≥ 0.05
   apart, middles ≥ 10° of crank apart; the radii made equal by moving the coupler point: Newton
   on g(u, v) = r1 − r2 along its gradient (finite differences at 1e-6 b; each vertex's radius
   is the extreme of r(φ) on a 0.1° window around it, refined by a parabola), the vertices
   followed as they move. A pair survives if |g| ≤ 1e-9 r within ``NEWTON`` steps, the point
   moved at most ``MOVE`` b, and the radius range, the separations and the link ratio still hold.
4. Per surviving pair and swing S ∈ {20°, 45°}: D on the bisector with C1–D–C2 = S (both sides);
   the branch condition checked at the two vertices (P at each, Q at its centre): pairs that fail
   it are counted and dropped. The rest: rocker |DC1|, rod r, the branch of the condition, and a
   tuning around it (``TUNE`` of measure_symmetric_double.py: rod × 0.995/1.005, D ±1 % of L
   across the bisector); each six-bar's figures at band 0.1° with two dwells and the rests'
   separation at 0.5° (:func:`synth.mechanism.figures.sixbar_figures`), tested per cell with the
   query's own :func:`synth.query.evaluate.meets` (default limits).
5. Where a nominal six-bar has two separated rests but swings more or less than S (the output
   overshoots a rest), the angle C1–D–C2 is corrected by the miss and the placement redone, for
   ``CORRECTIONS`` rounds.
6. The level set r1 = r2 walked: from every pair with a placement that passes the branch
   condition, the coupler point moved by ``WALK`` × b along the level set's tangent, equalised
   again, and 4–5 repeated on those pairs ("walked pairs"; "grid and walked pairs" is both).
7. Per cell, the ``NEAR`` six-bars within every limit but the dwell whose rests are nearest d,
   refined toward the cell's request as the query refines its nearest misses
   (:func:`synth.query.refine.refine`, ``reach=True``): how many then meet it.

Prints one JSON object: the counts of each stage, where Q sits at the two vertices, per cell the
six-bars meeting every default limit (and the distinct coupler curves among them) as placed and
refined, the best of each filled cell, the rests of the nominal placements, and the longest
pair of separated rests at each swing within every limit but the dwell.

    .venv/bin/python tests/synth/measure_equal_arcs.py std.sqlite          # 6 157 four-bars: 7 min, 2-core VM (shared)
    .venv/bin/python tests/synth/measure_equal_arcs.py std.sqlite --quick  # 154 four-bars, 2 min
"""

import json
import math
import sqlite3
import sys
from collections import Counter

import numpy as np
from measure_symmetric_double import (
    BAND,
    BLOCK,
    DWELLS,
    LEAVE,
    RADIUS,
    REQUESTS,
    SAMPLES,
    SWING_TOL,
    SWINGS,
    TUNE,
    rows_of,
    stationary_arcs,
)

from kinematics.fourbar import fourbar_motion
from synth.curvature.inflection import euler_savary
from synth.curvature.pole import pole
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.link_ratio import segment_link_ratio
from synth.mechanism.sixbar import SixBars, simulate
from synth.query.candidate_ids import dimension_vector
from synth.query.evaluate import meets, meets_but_dwells
from synth.query.refine import refine

QUICK = "--quick" in sys.argv
DB = next((x for x in sys.argv[1:] if not x.startswith("--")), "std.sqlite")
#: Every STRIDE-th four-bar of the atlas (ordered by id).
STRIDE = 40 if QUICK else 1
#: Coupler points p = b·(x + iy): x over GRID_X, y over GRID_Y.
GRID_X = np.linspace(-0.5, 1.5, 9)
GRID_Y = np.linspace(-1.5, 1.5, 9)
#: Two vertices are paired when their radii differ by at most this fraction of their mean.
PAIR_RADIUS = 0.05
#: The vertices' middles at least this far apart (rad of crank): nearer, they are one stretch.
PAIR_GAP = math.radians(10.0)
#: Half-width (rad) and samples of the window on which a vertex's radius is refined.
WINDOW, WINDOW_SAMPLES = math.radians(3.0), 61
NEWTON = 12
#: The largest move of the coupler point (× b) for the pair to count as the same pair.
MOVE = 0.25
CURVES = 6000  # coupler curves per block of the vertex search
#: Steps (× b) along the level set r1 = r2 from each pair that passes the branch condition.
WALK = (-0.08, -0.04, 0.04, 0.08)
#: Six-bars refined toward each cell: those within every limit but the dwell nearest it.
NEAR = 30
#: Six-bars shown per filled cell.
SHOWN = 5
#: Rounds that correct the step between the rests where a six-bar swings more than asked.
CORRECTIONS = 2


def fourbars(db: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, c, d) of every ``STRIDE``-th branch +1 four-bar of the atlas, transmission in [30°, 150°]."""
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as con:
        rows = con.execute(
            "SELECT b, c, d FROM linkage WHERE branch = 1 AND transmission_min >= ? AND transmission_max <= ? ORDER BY id",
            (math.radians(30.0), math.radians(150.0)),
        ).fetchall()
    b, c, d = np.array(rows[::STRIDE]).T
    return b, c, d


def vertex(b, c, d, u, v, phi0) -> tuple[np.ndarray, ...]:
    """The vertex of each coupler curve nearest crank angle ``phi0`` (rad) within ±``WINDOW``:
    (found, crank angle, radius, centre, path point). The radius is the extreme of r(φ) on the
    window's samples refined by the parabola through it and its neighbours; the centre and the
    point are evaluated at the refined angle."""
    offsets = np.linspace(-WINDOW, WINDOW, WINDOW_SAMPLES)
    step = offsets[1] - offsets[0]
    phi = phi0[:, None] + offsets
    motion = fourbar_motion(1.0, b[:, None], c[:, None], d[:, None], phi, 1, order=3)
    P = motion.coupler_point(u[:, None], v[:, None])[0]
    cc = euler_savary(pole(motion), P)
    r = cc.radius
    dr = np.diff(r, axis=1)
    turn = dr[:, :-1] * dr[:, 1:] < 0  # sample j + 1 is an extreme of r
    ok_window = (cc.status == 0).all(axis=1)
    centre_dist = np.where(turn, np.abs(np.arange(1, WINDOW_SAMPLES - 1) - WINDOW_SAMPLES // 2), WINDOW_SAMPLES)
    j = centre_dist.argmin(axis=1) + 1
    found = turn.any(axis=1) & ok_window
    rows = np.arange(b.size)
    r0, r1, r2 = r[rows, j - 1], r[rows, j], r[rows, j + 1]
    curv = r0 - 2 * r1 + r2
    t = np.divide(0.5 * (r0 - r2), curv, out=np.zeros_like(r1), where=curv != 0)
    t = np.clip(t, -1.0, 1.0)
    radius = r1 - 0.25 * (r0 - r2) * t
    angle = phi[rows, j] + t * step
    exact = fourbar_motion(1.0, b, c, d, angle, 1, order=3)
    Pv = exact.coupler_point(u, v)[0]
    cv = euler_savary(pole(exact), Pv)
    found &= cv.status == 0
    return found, angle, radius, cv.center, Pv


def equalise(b, c, d, u, v, phi1, phi2) -> tuple[np.ndarray, ...]:
    """Move each coupler point (u, v) until its two vertices (near ``phi1``, ``phi2``) have the
    same radius: Newton on g = r1 − r2 along ∇g (finite differences). Returns (converged, u, v,
    phi1, phi2, r1, r2, C1, C2, P1, P2, steps)."""
    h = 1e-6 * b
    alive = np.ones(b.size, bool)
    converged = np.zeros(b.size, bool)
    steps = np.zeros(b.size, int)
    u, v, phi1, phi2 = u.copy(), v.copy(), phi1.copy(), phi2.copy()
    for _ in range(NEWTON + 1):
        i = np.nonzero(alive & ~converged)[0]
        if i.size == 0:
            break
        args = (b[i], c[i], d[i])
        f1, a1, g1, *_ = vertex(*args, u[i], v[i], phi1[i])
        f2, a2, g2, *_ = vertex(*args, u[i], v[i], phi2[i])
        g = g1 - g2
        phi1[i], phi2[i] = a1, a2
        done = f1 & f2 & (np.abs(g) <= 1e-9 * 0.5 * (g1 + g2))
        converged[i[done]] = True
        alive[i[~(f1 & f2)]] = False
        going = f1 & f2 & ~done
        i, g = i[going], g[going]
        if i.size == 0 or _ == NEWTON:
            break
        args = (b[i], c[i], d[i])
        gu = vertex(*args, u[i] + h[i], v[i], phi1[i])[2] - vertex(*args, u[i] + h[i], v[i], phi2[i])[2]
        gv = vertex(*args, u[i], v[i] + h[i], phi1[i])[2] - vertex(*args, u[i], v[i] + h[i], phi2[i])[2]
        grad = np.stack([gu - g, gv - g]) / h[i]
        norm2 = (grad**2).sum(axis=0)
        move = -g * grad / np.where(norm2 > 0, norm2, np.inf)
        # a step longer than a tenth of b leaves the vertices' neighbourhood: cap it
        length = np.hypot(*move)
        move *= np.minimum(1.0, 0.1 * b[i] / np.where(length > 0, length, 1.0))
        u[i] += move[0]
        v[i] += move[1]
        steps[i] += 1
    f1, a1, r1, C1, P1 = vertex(b, c, d, u, v, phi1)
    f2, a2, r2, C2, P2 = vertex(b, c, d, u, v, phi2)
    converged &= f1 & f2
    return converged, u, v, a1, a2, r1, r2, C1, C2, P1, P2, steps


def vertex_pairs(b, c, d) -> dict[str, np.ndarray]:
    """Every pair of vertices of one coupler curve (four-bar × grid point) with radii within
    ``PAIR_RADIUS``, centres ≥ 0.05 apart and middles ≥ ``PAIR_GAP`` apart, before equalising."""
    gx, gy = np.meshgrid(GRID_X, GRID_Y)
    fb = np.repeat(np.arange(b.size), gx.size)
    u = b[fb] * np.tile(gx.ravel(), b.size)
    v = b[fb] * np.tile(gy.ravel(), b.size)
    keep = segment_link_ratio(1.0, b[fb], c[fb], d[fb], u, v) <= 10.0
    fb, u, v = fb[keep], u[keep], v[keep]
    phi = np.arange(SAMPLES) * (2 * math.pi / SAMPLES)
    out = {name: [] for name in ("curve", "k1", "k2", "r1", "r2")}
    vertices = 0
    for lo in range(0, fb.size, CURVES):
        s = slice(lo, lo + CURVES)
        motion = fourbar_motion(1.0, b[fb[s], None], c[fb[s], None], d[fb[s], None], phi, 1, order=3)
        P = motion.coupler_point(u[s, None], v[s, None])[0]
        assembled = (motion.status == 0).all(axis=1)
        row, k, C, rho = stationary_arcs(motion, P)
        ok = assembled[row]
        row, k, C, rho = row[ok], k[ok], C[ok], rho[ok]
        vertices += row.size
        # pairs within one curve: the vertices come sorted by curve, so pair each with the
        # m-th next for every m below the largest count per curve
        i, j = [np.zeros(0, int)], [np.zeros(0, int)]
        for m in range(1, int(np.bincount(row).max(initial=1))):
            same = np.nonzero(row[:-m] == row[m:])[0]
            i.append(same)
            j.append(same + m)
        i, j = np.concatenate(i).astype(int), np.concatenate(j).astype(int)
        gap = np.abs((k[i] - k[j] + SAMPLES // 2) % SAMPLES - SAMPLES // 2) * (2 * math.pi / SAMPLES)
        keep = (
            (np.abs(rho[i] - rho[j]) <= PAIR_RADIUS * 0.5 * (rho[i] + rho[j]))
            & (np.abs(C[i] - C[j]) > 0.05)
            & (gap >= PAIR_GAP)
        )
        i, j = i[keep], j[keep]
        for name, x in zip(out, (row[i] + lo, k[i], k[j], rho[i], rho[j])):
            out[name].append(x)
    out = {name: np.concatenate(x) for name, x in out.items()}
    out["fourbar"], out["u"], out["v"] = fb[out["curve"]], u[out["curve"]], v[out["curve"]]
    out["curves"], out["vertices"] = np.array(fb.size), np.array(vertices)
    return out


def placements(
    pairs: dict[str, np.ndarray], b, c, d, pair, swing, side, step
) -> tuple[SixBars, dict[str, np.ndarray], int]:
    """Per (equal ``pair``, requested ``swing`` (deg), ``side`` ±1, ``step`` (rad)): D on the
    bisector of C1C2 with C1–D–C2 = step on that side; the branch condition at the two vertices
    (P at each, Q at its centre); the six-bars of the placements that pass it (the branch of the
    condition) and their tuning ``TUNE``. Returns the six-bars, their columns and how many
    placements passed."""
    C1, C2, P1, P2 = (pairs[name][pair] for name in ("C1", "C2", "P1", "P2"))
    F, half = 0.5 * (C1 + C2), 0.5 * np.abs(C1 - C2)
    along = (C2 - C1) / np.abs(C2 - C1)
    rho = 0.5 * (pairs["r1"] + pairs["r2"])[pair]
    D0 = F + side * 1j * along * (half / np.tan(0.5 * step))
    s1 = np.sign(np.imag(np.conj(D0 - P1) * (C1 - P1)))
    s2 = np.sign(np.imag(np.conj(D0 - P2) * (C2 - P2)))
    idx = np.nonzero((s1 == s2) & (s1 != 0))[0]
    names = ("pair", "swing", "side", "step", "nominal", "pivot", "rocker", "rod", "dyad_branch")
    cols = {name: [] for name in names}
    for rod_factor, across in TUNE:
        D = D0[idx] + across * np.abs(D0[idx] - C1[idx]) * along[idx]
        values = (pair[idx], swing[idx], side[idx], step[idx], np.full(idx.size, rod_factor == 1.0 and across == 0.0))
        values += (D, np.abs(D - C1[idx]), rho[idx] * rod_factor, s1[idx])
        for name, x in zip(names, values):
            cols[name].append(x)
    cols = {name: np.concatenate(x) for name, x in cols.items()}
    fb = pairs["fourbar"][cols["pair"]]
    ones, at = np.ones(fb.size), cols["pair"]
    fourbar = {"a": ones, "b": b[fb], "c": c[fb], "d": d[fb], "branch": ones, "u": pairs["u"][at], "v": pairs["v"][at]}
    dyad = {name: cols[name] for name in ("pivot", "rocker", "rod", "dyad_branch")}
    sixbars = SixBars(**fourbar, rpr=np.zeros(fb.size, bool), **dyad)
    for name in ("phi1", "phi2", "C1", "C2"):
        cols[name] = pairs[name][cols["pair"]]
    cols |= {name: x for name, x in fourbar.items() if name in ("b", "c", "d", "u", "v")}
    return sixbars, cols, int(idx.size)


def evaluate(sixbars: SixBars, cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each six-bar's figures (band 0.1°, two dwells, separation 0.5°), per row: whether Q sits
    at both vertices' centres, whether it has two separated rests, the shorter and the longer
    (rad), its swing (rad), whether it meets every limit of its swing's request but the dwell,
    the first limit it misses, and per cell whether it meets that cell's request."""
    rows: dict[str, list] = {
        name: [] for name in ("at_both", "two", "shorter", "longer", "swing_measured", "within", "miss")
    }
    rows |= {f"cell {dw}": [] for dw in DWELLS}
    best: dict = {S: (0.0, None, None) for S in SWINGS}
    shown: dict = {key: [] for key in REQUESTS}
    for lo in range(0, len(sixbars), BLOCK):
        s = slice(lo, lo + BLOCK)
        batch = rows_of(sixbars, s)
        phi1, phi2, C1, C2 = (cols[name][s] for name in ("phi1", "phi2", "C1", "C2"))
        Q = simulate(batch, np.stack([phi1, phi2], axis=1), order=0).moving_pivot
        tol = 1e-6 * batch.rocker
        rows["at_both"] += ((np.abs(Q[:, 0] - C1) < tol) & (np.abs(Q[:, 1] - C2) < tol)).tolist()
        figures = sixbar_figures(batch, band=BAND, dwells=2, samples=SAMPLES, footprint=False, leave=LEAVE)
        for q, (f, S) in enumerate(zip(figures, cols["swing"][s].tolist())):
            two = len(f.dwells) == 2 and f.rests_apart(LEAVE)
            rests = sorted(x.angle for x in f.dwells) if two else [0.0, 0.0]
            within = meets_but_dwells(REQUESTS[(S, DWELLS[0])], f)
            for name, x in zip(
                ("two", "shorter", "longer", "swing_measured", "within", "miss"),
                (two, rests[0], rests[1], f.swing, within, failure(REQUESTS[(S, DWELLS[0])], f)),
            ):
                rows[name].append(x)
            for dw in DWELLS:
                hit = meets(REQUESTS[(S, dw)], f)
                rows[f"cell {dw}"].append(hit)
                if hit:
                    # the cell's six-bars, best transmission first, to check by hand
                    mu = min(f.transmission_fourbar, f.transmission_output)
                    shown[(S, dw)] = sorted(
                        [*shown[(S, dw)], (mu, lo + q, f, rows_of(batch, [q])[0])], key=lambda t: -t[0]
                    )[:SHOWN]
            if two and within and rests[0] > best[S][0]:
                best[S] = (rests[0], f, rows_of(batch, [q])[0])
    out = {name: np.array(x) for name, x in rows.items()}
    out["best"], out["shown"] = best, shown
    return out


def summary(cols: dict[str, np.ndarray], res: dict[str, np.ndarray]) -> dict:
    """The figures of :func:`evaluate` over every round, per swing."""
    out: dict = {"six-bars simulated": int(res["two"].size)}
    nominal = cols["nominal"]
    out["Q at both centres at the two vertices: nominal placements, of them"] = [
        int(nominal.sum()),
        int(res["at_both"][nominal].sum()),
    ]
    for S in SWINGS:
        mine = cols["swing"] == S
        out[f"swing {S}: six-bars meeting every default limit with two rests of d +- 5"] = {
            str(dw): int((res[f"cell {dw}"] & mine).sum()) for dw in DWELLS
        }
        out[f"swing {S}: distinct coupler curves (equal pairs) among them"] = {
            str(dw): int(np.unique(cols["pair"][res[f"cell {dw}"] & mine]).size) for dw in DWELLS
        }
        two = mine & nominal & res["two"]
        short = np.degrees(res["shorter"][two])
        out[
            f"swing {S}: nominal placements; with two separated rests; shorter rest (deg) min, 10th pct, median, 90th pct, max"
        ] = [
            int((mine & nominal).sum()),
            int(two.sum()),
            [round(float(np.percentile(short, p)), 2) for p in (0, 10, 50, 90, 100)] if short.size else None,
        ]
        real = mine & res["two"] & (res["shorter"] >= math.radians(5.0))
        out[f"swing {S}: six-bars with two separated rests >= 5 deg: first limit (but the dwell) missed"] = dict(
            Counter(res["miss"][real].tolist()).most_common()
        )
        ok = real & res["within"]
        if ok.any():
            gap = np.degrees(res["longer"][ok] - res["shorter"][ok])
            out[
                f"swing {S}: within every limit but the dwell: six-bars; shorter rest (deg) min, max; longer - shorter (deg) median, min"
            ] = [
                int(ok.sum()),
                round(float(np.degrees(res["shorter"][ok].min())), 2),
                round(float(np.degrees(res["shorter"][ok].max())), 2),
                round(float(np.median(gap)), 2),
                round(float(gap.min()), 2),
            ]
        _, f, sb = res["best"][S]
        out[f"swing {S}: longest pair of separated rests within every limit but the dwell (deg)"] = described(f, sb)
        for dw in DWELLS:
            if res["shown"][(S, dw)]:
                out[f"swing {S}, dwell {dw}: six-bars, best transmission first"] = [
                    described(f, sb) for _, _, f, sb in res["shown"][(S, dw)]
                ]
    return out


def described(f, sb) -> dict | None:
    """A six-bar and its figures as the report gives them (angles in degrees), enough to rebuild
    it for `dwell analyze`."""
    if f is None:
        return None
    dyad = sb.dyad
    deg = {
        "rests": [x.angle for x in f.dwells],
        "swing": f.swing,
        "step": f.step,
        "transmission (fourbar, output)": [f.transmission_fourbar, f.transmission_output],
    }
    out = {name: np.round(np.degrees(x), 3).tolist() for name, x in deg.items()}
    out["link ratio"] = round(f.link_ratio, 3)
    dims = (sb.b, sb.c, sb.d, sb.u, sb.v, dyad.pivot.real, dyad.pivot.imag, dyad.rocker, dyad.rod)
    out["six-bar (b, c, d, u, v; pivot x, y, rocker, rod, branch)"] = [round(float(x), 6) for x in dims] + [dyad.branch]
    return out


def refined(cols: dict[str, np.ndarray], res: dict[str, np.ndarray]) -> dict:
    """Per cell, the ``NEAR`` six-bars within every limit but the dwell whose two rests are
    nearest d (the larger of |rest − d|), refined toward the cell's request as the query refines
    its nearest misses (:func:`synth.query.refine.refine`, ``reach=True``): how many then meet
    it, from how many distinct coupler curves, the best (highest smallest transmission angle)."""
    out: dict = {}
    for S in SWINGS:
        ok = np.flatnonzero((cols["swing"] == S) & res["two"] & res["within"])
        for dw in DWELLS:
            request = REQUESTS[(S, dw)]
            off = np.maximum(np.abs(res["shorter"][ok] - request.dwell), np.abs(res["longer"][ok] - request.dwell))
            near = ok[np.argsort(off, kind="stable")[:NEAR]]
            if near.size == 0:
                continue
            batch = SixBars(
                **{
                    name: cols[name][near]
                    for name in ("b", "c", "d", "u", "v", "pivot", "rocker", "rod", "dyad_branch")
                },
                a=np.ones(near.size),
                branch=np.ones(near.size),
                rpr=np.zeros(near.size, bool),
            )
            sixbars = [batch[k] for k in range(near.size)]
            before = sixbar_figures(
                batch, band=BAND, dwell_length=request.dwell, dwells=2, leave=LEAVE, footprint=False
            )
            after = refine(request, sixbars, before, reach=True)
            hit = [k for k, r in enumerate(after) if r.meets]
            best = max(
                hit,
                key=lambda k: min(after[k].figures.transmission_fourbar, after[k].figures.transmission_output),
                default=None,
            )
            out[f"swing {S}, dwell {dw}"] = {
                "started from; nearest start's rests (deg)": [
                    int(near.size),
                    np.round(np.degrees([res["shorter"][near[0]], res["longer"][near[0]]]), 2).tolist(),
                ],
                "meeting the request after refinement; from distinct coupler curves; distinct to 1e-3": [
                    len(hit),
                    int(np.unique(cols["pair"][near[hit]]).size),
                    len({tuple(np.round(dimension_vector(after[k].sixbar), 3)) for k in hit}),
                ],
                "best": None if best is None else described(after[best].figures, after[best].sixbar),
            }
    return out


def failure(request, f) -> str:
    """The first default limit (but the dwell) that figures ``f`` miss, or "none"."""
    if not f.acceptable:
        return "assembly/toggle/revolving"
    if abs(f.swing - request.swing) > request.swing_tol:
        return "swing"
    if min(f.transmission_fourbar, f.transmission_output) < request.min_transmission:
        return "transmission"
    if f.build is not None and f.build.clearance < request.min_clearance:
        return "clearance"
    if f.link_ratio > request.max_link_ratio:
        return "link ratio"
    return "none"


def equal(b, c, d, fb, u0, v0, phi1, phi2, out: dict, label: str) -> dict[str, np.ndarray]:
    """Equalise the vertex pairs starting at coupler points (``u0``, ``v0``) of four-bars ``fb``
    with vertices near ``phi1``, ``phi2``; the counts go to ``out`` under ``label``. Returns the
    surviving equal pairs (four-bar, point, vertices' angles, radii, centres and path points)."""
    conv, u, v, a1, a2, r1, r2, C1, C2, P1, P2, steps = equalise(b[fb], c[fb], d[fb], u0, v0, phi1, phi2)
    moved = np.hypot(u - u0, v - v0) / b[fb]
    gap = np.abs(np.angle(np.exp(1j * (a1 - a2))))
    survive = (
        conv
        & (moved <= MOVE)
        & (r1 > RADIUS[0])
        & (r1 < RADIUS[1])
        & (np.abs(C1 - C2) > 0.05)
        & (gap >= PAIR_GAP)
        & (segment_link_ratio(1.0, b[fb], c[fb], d[fb], u, v) <= 10.0)
    )
    out[f"{label}: pairs; converged; surviving (moved <= {MOVE} b, still a pair)"] = [
        int(u0.size),
        int(conv.sum()),
        int(survive.sum()),
    ]
    if survive.any():
        out[f"{label}: point moved (x b): median, max; Newton steps: median, max; max |r1 - r2| / r"] = [
            round(float(np.median(moved[survive])), 4),
            round(float(moved[survive].max()), 4),
            int(np.median(steps[survive])),
            int(steps[survive].max()),
            float((np.abs(r1 - r2) / r1)[survive].max()),
        ]
    eq = {"fourbar": fb, "u": u, "v": v, "phi1": a1, "phi2": a2, "r1": r1, "r2": r2}
    eq |= {"C1": C1, "C2": C2, "P1": P1, "P2": P2}
    return {name: x[survive] for name, x in eq.items()}


def rounds(eq: dict[str, np.ndarray], b, c, d, out: dict, label: str) -> tuple[dict, dict]:
    """Place, simulate and test every equal pair of ``eq`` at both swings and sides, then correct
    the step where a nominal six-bar with two rests misses its swing. Returns the columns and
    the figures of every six-bar (:func:`placements`, :func:`evaluate`)."""
    n = eq["u"].size
    # round 0: the step between the rests is the requested swing; rounds 1..: where a nominal
    # six-bar with two rests swings more or less than asked (the output overshoots a rest),
    # the step corrected by the miss (a secant step with slope 1)
    pair = np.tile(np.arange(n), 2 * len(SWINGS))
    swing = np.repeat(np.array(SWINGS * 2), n)
    side = np.repeat(np.array([1] * len(SWINGS) + [-1] * len(SWINGS)), n)
    step = np.radians(swing.astype(float))
    every_cols, every_res = [], []
    for round_ in range(1 + CORRECTIONS):
        sixbars, cols, passed = placements(eq, b, c, d, pair, swing, side, step)
        out[f"{label}, round {round_}: placements; passing the branch condition"] = [int(pair.size), passed]
        res = evaluate(sixbars, cols)
        every_cols.append(cols)
        every_res.append(res)
        redo = cols["nominal"] & res["two"] & (np.abs(res["swing_measured"] - np.radians(cols["swing"])) > SWING_TOL)
        pair, swing, side = cols["pair"][redo], cols["swing"][redo], cols["side"][redo]
        step = cols["step"][redo] + np.radians(swing) - res["swing_measured"][redo]
        ok = (step > math.radians(2.0)) & (step < math.radians(170.0))
        pair, swing, side, step = pair[ok], swing[ok], side[ok], step[ok]
        if pair.size == 0:
            break
    return joined(every_cols, every_res)


def joined(every_cols: list[dict], every_res: list[dict], offsets=None) -> tuple[dict, dict]:
    """The columns and figures of several batches as one (pair ids shifted by ``offsets``)."""
    offsets = offsets or [0] * len(every_cols)
    cols = {name: np.concatenate([x[name] for x in every_cols]) for name in every_cols[0]}
    cols["pair"] = np.concatenate([x["pair"] + o for x, o in zip(every_cols, offsets)])
    res = {name: np.concatenate([x[name] for x in every_res]) for name in every_res[0] if name not in ("best", "shown")}
    res["best"] = {S: max((x["best"][S] for x in every_res), key=lambda t: t[0]) for S in SWINGS}
    res["shown"] = {
        key: sorted((t for x in every_res for t in x["shown"][key]), key=lambda t: -t[0])[:SHOWN] for key in REQUESTS
    }
    return cols, res


def walked(eq: dict[str, np.ndarray], cols: dict, b, c, d) -> tuple[np.ndarray, ...]:
    """Starts along the level set r1 = r2 of the pairs with a placement that passes the branch
    condition: their coupler point moved by τ·b, τ in ``WALK``, along the tangent of the level
    set (⊥ ∇(r1 − r2), finite differences). Returns (four-bar, u, v, phi1, phi2)."""
    i = np.unique(cols["pair"])
    fb, u, v, phi1, phi2 = (eq[name][i] for name in ("fourbar", "u", "v", "phi1", "phi2"))
    h = 1e-6 * b[fb]
    args = (b[fb], c[fb], d[fb])

    def g(du, dv):
        return vertex(*args, u + du, v + dv, phi1)[2] - vertex(*args, u + du, v + dv, phi2)[2]

    g0 = g(0.0, 0.0)
    gu, gv = (g(h, 0.0) - g0) / h, (g(0.0, h) - g0) / h
    norm = np.hypot(gu, gv)
    tu, tv = -gv / norm, gu / norm
    tau = np.repeat(np.array(WALK), i.size)
    rep = np.tile(np.arange(i.size), len(WALK))
    scale = tau * b[fb][rep]
    return fb[rep], u[rep] + scale * tu[rep], v[rep] + scale * tv[rep], phi1[rep], phi2[rep]


def main() -> None:
    b, c, d = fourbars(DB)
    out: dict = {"four-bars": int(b.size)}
    pairs = vertex_pairs(b, c, d)
    out["coupler curves (grid points, plate link ratio <= 10)"] = int(pairs.pop("curves"))
    out["vertices (radius 0.2-8)"] = int(pairs.pop("vertices"))
    out[f"vertex pairs, radii within {PAIR_RADIUS:.0%}"] = int(pairs["curve"].size)
    phi = np.arange(SAMPLES) * (2 * math.pi / SAMPLES)
    eq = equal(b, c, d, pairs["fourbar"], pairs["u"], pairs["v"], phi[pairs["k1"]], phi[pairs["k2"]], out, "grid")
    cols, res = rounds(eq, b, c, d, out, "grid")
    out["grid pairs"] = summary(cols, res)
    # the level set r1 = r2 through the pairs that pass the branch condition, walked
    eq2 = equal(b, c, d, *walked(eq, cols, b, c, d), out, "walk")
    cols2, res2 = rounds(eq2, b, c, d, out, "walk")
    out["walked pairs"] = summary(cols2, res2)
    both = joined([cols, cols2], [res, res2], [0, eq["u"].size])
    out["grid and walked pairs"] = summary(*both)
    out["refined toward each cell"] = refined(*both)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
