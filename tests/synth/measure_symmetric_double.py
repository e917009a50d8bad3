"""RRR double dwells from symmetric coupler curves (docs/query-double-dwell.md, last section):
can a rocker and rod resting on two mirror arcs of one symmetric coupler curve give two
separated rests of d ± 5° at a swing of 20° or 45°?

The family: crank a = 1, coupler b, rocker c = b, ground d, coupler point P on the circle of
radius b about B (|BP| = |BA| = |BB0|; coupler angle γ = ∠ABP, p = b(1 − e^{iγ})), Grashof
crank-rockers whose transmission angle stays ≥ 30° (1 + 0.518 b ≤ d ≤ 1.932 b − 1), branch +1
(branch −1 is the mirror image about the ground line, covered by γ over the whole turn).

1. The curve's mirror symmetry, checked on the simulation: P(−φ) is the mirror image of P(φ)
   about the line through B0 at angle arg(A0 − B0) + γ/2 (the largest distance over the
   family is printed, and the axis fitted from the samples is compared with that line).
2. The arcs: the crank angles in (0°, 180°) where the path's radius of curvature
   (Euler–Savary, :func:`synth.curvature.inflection.euler_savary`, at every 0.5° of crank) is
   stationary — points of the cubic of stationary curvature — with centre C1 and radius r;
   the mirror arc is traversed at −φ about C2, the mirror image of C1, with the same radius.
3. For each arc pair and swing S ∈ {20°, 45°}: the rocker pivot D on the axis with angle
   C1–D–C2 = S (both sides), rocker L = |D − C1|, rod r, both dyad branches; around that, a
   tuning (rod × 0.995 and × 1.005, D moved ±1 % of L across the axis). Each
   six-bar's figures at band 0.1° with two dwells and the rests' separation at 0.5°
   (:func:`synth.mechanism.figures.sixbar_figures`), tested against the default limits by the
   query's own :func:`synth.query.evaluate.meets` for each cell's request.
4. The same for pairs of arcs of one curve that are not mirror images, radii within
   ``PAIR_RADIUS`` (the rod their mean), D on the perpendicular bisector of their centres.

No placement can rest on both arcs of a mirror pair: D on the axis makes the triangle
(P′, D, C2) on the mirror arc the mirror image of (P, D, C1), so Q = C2 needs the other dyad
branch (the count of "at C1, at C2" shows it).

Prints one JSON object: the symmetry check, the arcs, where the moving pivot Q sits at the two
arcs' middles (at C1, at C2, at both), the cells, the longest pair of separated rests at each
swing and how far the output moves over the mirror arc's crank interval of a six-bar resting on
the first arc.

    .venv/bin/python tests/synth/measure_symmetric_double.py            # 3 min 20 s on a 2-core VM (shared)
    .venv/bin/python tests/synth/measure_symmetric_double.py --quick    # 1 008 four-bars, ~25 s
"""

import json
import math
import sys
from collections import Counter

import numpy as np

from kinematics.fourbar import fourbar_motion
from synth.curvature.inflection import euler_savary
from synth.curvature.pole import pole
from synth.mechanism.figures import sixbar_figures
from synth.mechanism.link_ratio import segment_link_ratio
from synth.mechanism.sixbar import SixBars, crank_grid, output_angle, simulate
from synth.query.candidates import Request
from synth.query.evaluate import meets, meets_but_dwells

QUICK = "--quick" in sys.argv
DWELLS = (10, 20, 30, 45, 60, 75, 90, 120)
SWINGS = (20, 45)
BAND, LEAVE, DWELL_TOL, SWING_TOL = (math.radians(x) for x in (0.1, 0.5, 5.0, 0.5))
SAMPLES = 720
#: Arcs whose radius of curvature is outside this range (cranks) are left out: a tighter one
#: makes the rod the shortest link by far, a wider one is a straight stretch.
RADIUS = (0.2, 8.0)
#: Each placement and its tuning around it: (rod factor, D's move across the axis × L).
TUNE = ((1.0, 0.0), (0.995, 0.0), (1.005, 0.0), (1.0, 0.01), (1.0, -0.01))
BLOCK = 4000
#: Two arcs of one curve that are not mirror images are paired when their radii differ by
#: at most this fraction of their mean (the rod is the mean).
PAIR_RADIUS = 0.02


def family() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, d, γ) of the sampled four-bars (b = c, P at distance b from B)."""
    bs = np.linspace(1.45, 6.0, 8 if QUICK else 16)
    gammas = np.radians(np.arange(0.0, 360.0, 10.0 if QUICK else 5.0))
    rows = []
    for b in bs:
        # the transmission angle is extreme at |B0 − A| = d ∓ 1, where (c = b) it is
        # 2·asin((d ∓ 1)/2b): ≥ 30° and ≤ 150° ask d − 1 ≥ 2b·sin 15°, d + 1 ≤ 2b·sin 75°
        lo, hi = 1.0 + 0.5176 * b, 1.9319 * b - 1.0
        if hi <= lo:
            continue
        for d in np.linspace(lo, hi, 4 if QUICK else 7):
            rows += [(b, d, g) for g in gammas]
    b, d, g = np.array(rows).T
    u, v = b * (1 - np.cos(g)), -b * np.sin(g)
    keep = segment_link_ratio(1.0, b, b, d, u, v) <= 10.0
    return b[keep], d[keep], g[keep]


def axis(d: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The symmetry axis: the point B0 and its unit direction arg(A0 − B0) + γ/2."""
    return d.astype(complex), np.exp(1j * (math.pi + 0.5 * g))


def mirror(z, origin, direction):
    """The mirror image of ``z`` about the line through ``origin`` along unit ``direction``."""
    return origin + direction**2 * np.conj(z - origin)


def stationary_arcs(motion, P: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every sample where the path's radius of curvature is stationary (a point of the cubic of
    stationary curvature at that crank angle), within ``RADIUS``: (row, sample, centre, radius)."""
    centre = euler_savary(pole(motion), P)
    r = centre.radius
    dr = np.roll(r, -1, axis=1) - r
    stationary = (dr * np.roll(dr, 1, axis=1) < 0) & (centre.status == 0)
    row, k = np.nonzero(stationary & (r > RADIUS[0]) & (r < RADIUS[1]))
    return row, k, centre.center[row, k], r[row, k]


def placements(row, k1, k2, C1, C2, rho1, rho2) -> tuple[SixBars, dict[str, np.ndarray]]:
    """The six-bars of arc pairs (four-bar ``row``, middles at samples ``k1``, ``k2``, centres
    ``C1``, ``C2``, radii ``rho1``, ``rho2``; the rod their mean): for each swing S, D on the perpendicular bisector of C1C2 with
    angle C1–D–C2 = S (both sides), rocker |D − C1|, both dyad branches, and the tuning ``TUNE``
    around each; with, per six-bar, its pair, swing (deg) and whether it is the nominal one."""
    F, h = 0.5 * (C1 + C2), 0.5 * np.abs(C1 - C2)
    bisector = 1j * (C2 - C1) / np.abs(C2 - C1)
    cols = {name: [] for name in ("pair", "swing", "nominal", "pivot", "rocker", "rod", "dyad_branch")}
    for S in SWINGS:
        for side in (1, -1):
            D0 = F + side * bisector * (h / math.tan(math.radians(S) / 2))
            for rod_factor, across in TUNE:
                D = D0 + across * np.abs(D0 - C1) * (C2 - C1) / np.abs(C2 - C1)
                for branch in (1.0, -1.0):
                    for name, x in zip(
                        cols,
                        (
                            np.arange(row.size),
                            np.full(row.size, S),
                            np.full(row.size, rod_factor == 1.0 and across == 0.0),
                            D,
                            np.abs(D - C1),
                            0.5 * (rho1 + rho2) * rod_factor,
                            np.full(row.size, branch),
                        ),
                    ):
                        cols[name].append(x)
    cols = {name: np.concatenate(x) for name, x in cols.items()}
    i = row[cols["pair"]]
    ones = np.ones(i.size)
    sixbars = SixBars(
        a=ones,
        b=B[i],
        c=B[i],
        d=GROUND[i],
        branch=ones,
        u=U[i],
        v=V[i],
        rpr=np.zeros(i.size, bool),
        pivot=cols["pivot"],
        rocker=cols["rocker"],
        rod=cols["rod"],
        dyad_branch=cols["dyad_branch"],
    )
    for name, x in zip(("k1", "k2", "C1", "C2", "rho1", "rho2"), (k1, k2, C1, C2, rho1, rho2)):
        cols[name] = x[cols["pair"]]
    return sixbars, cols


def rows_of(batch: SixBars, index) -> SixBars:
    return SixBars(*(getattr(batch, name)[index] for name in SixBars.__dataclass_fields__))


def evaluate(sixbars: SixBars, cols: dict[str, np.ndarray]) -> dict:
    """Each six-bar's figures (band 0.1°, two dwells, separation 0.5°) and the query's test per
    cell; where Q sits at the two arcs' middles; the longest pair of separated rests per swing
    (within every default limit but the dwell); the six-bars resting on the first arc: that
    rest, and how far the output moves over the crank interval of the second arc's rest."""
    phi = crank_grid(SAMPLES)
    cells = {key: 0 for key in REQUESTS}
    at = Counter()
    longest = {S: (0.0, None, None) for S in SWINGS}
    one_rest, moved = {S: [] for S in SWINGS}, {S: [] for S in SWINGS}
    for lo in range(0, len(sixbars), BLOCK):
        s = slice(lo, lo + BLOCK)
        batch = rows_of(sixbars, s)
        k1, k2, C1, C2, swing = (cols[name][s] for name in ("k1", "k2", "C1", "C2", "swing"))
        Q = simulate(batch, np.stack([phi[k1], phi[k2]], axis=1), order=0).moving_pivot
        # Q at a centre: to rounding, or to twice the rod's mismatch with that arc's radius
        tol = (
            1e-6 * batch.rocker + 2 * np.abs(batch.rod - cols["rho1"][s]),
            1e-6 * batch.rocker + 2 * np.abs(batch.rod - cols["rho2"][s]),
        )
        on1, on2 = np.abs(Q[:, 0] - C1) < tol[0], np.abs(Q[:, 1] - C2) < tol[1]
        at.update(zip(on1[cols["nominal"][s]].tolist(), on2[cols["nominal"][s]].tolist()))
        figures = sixbar_figures(batch, band=BAND, dwells=2, samples=SAMPLES, footprint=False, leave=LEAVE)
        resting, spans = [], []
        for q, (f, S) in enumerate(zip(figures, swing.tolist())):
            if meets_but_dwells(REQUESTS[(S, DWELLS[0])], f) and len(f.dwells) == 2 and f.rests_apart(LEAVE):
                shorter = min(x.angle for x in f.dwells)
                if shorter > longest[S][0]:
                    longest[S] = (shorter, f, rows_of(batch, [q])[0])
            for dw in DWELLS:
                cells[(S, dw)] += meets(REQUESTS[(S, dw)], f)
            if on1[q] and f.acceptable and f.dwells:
                # the rest on the first arc, and the second arc's crank interval: the first's
                # moved by the samples between the two arcs' middles
                first = max(f.dwells, key=lambda x: x.angle)
                one_rest[S].append((first.angle, f.swing, meets_but_dwells(REQUESTS[(S, DWELLS[0])], f)))
                shift = (k2[q] - k1[q]) * (2 * math.pi / SAMPLES)
                resting.append(q)
                spans.append(np.linspace(first.start + shift, first.end + shift, 181))
        if resting:
            psi = output_angle(rows_of(batch, resting), np.array(spans))
            for S, x in zip(swing[resting].tolist(), np.ptp(psi, axis=1).tolist()):
                moved[S].append(x)
    out: dict = {
        "six-bars simulated": len(sixbars),
        "Q at the middles of the two arcs, nominal placements (at C1, at C2): count": {
            f"{a}, {c}": int(x) for (a, c), x in sorted(at.items())
        },
    }
    for S in SWINGS:
        out[f"swing {S}: six-bars meeting every default limit with two rests of d +- 5"] = {
            str(dw): int(cells[(S, dw)]) for dw in DWELLS
        }
        _, f, sb = longest[S]
        out[f"swing {S}: longest pair of separated rests within every limit but the dwell (deg)"] = (
            None
            if f is None
            else {
                "rests": [round(math.degrees(x.angle), 2) for x in f.dwells],
                "swing": round(math.degrees(f.swing), 2),
                "step": round(math.degrees(f.step), 2),
                "six-bar (b = c, d, u, v; pivot, rocker, rod, branch)": [
                    round(x, 6) for x in (sb.b, sb.d, sb.u, sb.v, sb.dyad.pivot.real, sb.dyad.pivot.imag)
                ]
                + [round(sb.dyad.rocker, 6), round(sb.dyad.rod, 6), sb.dyad.branch],
            }
        )
        if one_rest[S]:
            rest, whole, within = (np.array(x) for x in zip(*one_rest[S]))
            rest, whole, move = np.degrees(rest), np.degrees(whole), np.degrees(moved[S])
            still = move < math.degrees(SWING_TOL)
            out[f"swing {S}: resting on the first arc (Q = C1)"] = {
                "six-bars": int(rest.size),
                "rest (deg): median, max": [round(float(np.median(rest)), 1), round(float(rest.max()), 1)],
                "output motion over the second arc's crank interval (deg): min, median": [
                    round(float(move.min()), 2),
                    round(float(np.median(move)), 2),
                ],
                "moving less than the swing tolerance there: count, largest swing (deg), within the limits": [
                    int(still.sum()),
                    round(float(whole[still].max()), 2) if still.any() else None,
                    int((still & within).sum()),
                ],
            }
    return out


B, GROUND, GAMMA = family()
U, V = B * (1 - np.cos(GAMMA)), -B * np.sin(GAMMA)
REQUESTS = {
    (S, dw): Request(
        dwell=math.radians(dw),
        dwell_tol=DWELL_TOL,
        swing=math.radians(S),
        swing_tol=SWING_TOL,
        dwells=2,
        output="any",  # meets reads the figures, not the output kind; "rrr" refuses two dwells
    )
    for S in SWINGS
    for dw in DWELLS
}


def main() -> None:
    out: dict = {}
    phi = crank_grid(SAMPLES)
    motion = fourbar_motion(1.0, B[:, None], B[:, None], GROUND[:, None], phi, 1, order=3)
    P = motion.coupler_point(U[:, None], V[:, None])[0]
    origin, direction = axis(GROUND, GAMMA)
    # 1. symmetry: P(−φ) against the mirror image of P(φ); the axis fitted from the samples
    back = P[:, (-np.arange(SAMPLES)) % SAMPLES]
    error = np.abs(mirror(P, origin[:, None], direction[:, None]) - back).max(axis=1)
    ratio = (back - origin[:, None]) / np.conj(P - origin[:, None])  # e^{2iβ} on every sample
    fitted = np.angle(ratio.mean(axis=1)) / 2
    axis_error = np.abs(np.angle(np.exp(2j * (fitted - np.angle(direction))))) / 2
    assembled = (motion.status == 0).all(axis=1)
    out["four-bars"] = int(B.size)
    out["assembled over the turn"] = int(assembled.sum())
    out["symmetry: max |mirror(P(phi)) - P(-phi)| (cranks)"] = float(error[assembled].max())
    out["symmetry: max |fitted axis - closed form| (deg)"] = float(np.degrees(axis_error[assembled].max()))

    # 2. arcs with their mirror arcs: middles in (0°, 180°), the mirror's at −φ
    row, k, C, rho = stationary_arcs(motion, P)
    ok = assembled[row]
    row, k, C, rho = row[ok], k[ok], C[ok], rho[ok]
    first = (k > 1) & (k < SAMPLES // 2 - 1)  # away from 0° and 180°, where an arc is its own mirror
    C2 = mirror(C[first], origin[row[first]], direction[row[first]])
    apart = np.abs(C[first] - C2) > 0.05
    pair = [x[first][apart] for x in (row, k, C)] + [C2[apart], rho[first][apart]]
    out["arcs over the turn (stationary curvature, radius 0.2-8)"] = int(row.size)
    out["mirror pairs (middle in (0, 180) deg, centres 0.05 apart or more)"] = int(pair[0].size)
    r, k1, c1, c2, rr = pair
    out["mirror pairs"] = evaluate(*placements(r, k1, (SAMPLES - k1) % SAMPLES, c1, c2, rr, rr))

    # 3. pairs of arcs of one curve that are not mirror images, radii within PAIR_RADIUS
    i, j = np.nonzero(
        (row[:, None] == row[None, :])
        & (np.arange(row.size)[:, None] < np.arange(row.size)[None, :])
        & (np.abs(rho[:, None] - rho[None, :]) <= PAIR_RADIUS * 0.5 * (rho[:, None] + rho[None, :]))
        & (np.abs(C[:, None] - C[None, :]) > 0.05)
        & (np.abs((k[:, None] + k[None, :] + 1) % SAMPLES - 1) > 1)  # not k2 = −k1 (± 1 sample)
    )
    out[f"other pairs (radii within {PAIR_RADIUS:.0%}, centres 0.05 apart or more)"] = int(i.size)
    if i.size:
        out["other pairs"] = evaluate(*placements(row[i], k[i], k[j], C[i], C[j], rho[i], rho[j]))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
