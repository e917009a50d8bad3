"""``dwell bench stability``: the curvature engine on random and adversarial cases.

Every case is one (linkage, crank angle). Each is evaluated by the public ``synth`` kernels
(flag mode): pole, inflection circle, Ball's point, line scanning on six rays (two random,
and the pole tangent and normal each ± U(0, 1e-12) rad) and the Euler–Savary centre of a
coupler point near the linkage and of one 1e6 crank lengths away. Case families:

* ``random_ratios``: crank 1, b, c, d log-uniform in [1e-3, 1e3], crank angle drawn where the
  loop closes (if anywhere);
* ``change_point``: s + l = p + q (one link then scaled by 1 ± 1e-12), a third of them within
  1e-9 rad of the flat position;
* ``near_toggle``: linkages whose crank cannot turn fully, within 1e-9 rad of a toggle;
* ``near_translation``: crank-rockers within 1e-9 rad of θ′ = 0 (pole at infinity);
* ``crank_rocker``: ordinary crank-rockers (the rays and far points are the adversaries).

The summary counts flags per reason for every kind of result (and items and flagged items per
family), checks that no value is NaN or inf (flagged or not), counts exceptions by type (and,
in ``on_degenerate="raise"`` mode on the first cases, that only the documented
``AssemblyError`` escapes), and gives the largest residual of the unflagged results against
the extended-precision reference: a distance over max(crank, distance of the point from the
crank pin), see :func:`cli.bench.reference.residuals`.
"""

from __future__ import annotations

import json
import time

import click
import numpy as np

from cli.bench import reference
from cli.bench.curvature import crank_rockers
from cli.options import SEED
from kinematics.fourbar import fourbar_motion
from kinematics.status import AssemblyError, Status
from synth.curvature.ball import ball_point
from synth.curvature.inflection import euler_savary, inflection_circle
from synth.curvature.line_scan import line_scan
from synth.curvature.pole import pole

FAMILIES = ("random_ratios", "change_point", "near_toggle", "near_translation", "crank_rocker")
#: Cases per evaluation batch (an exception is then retried case by case to count it).
BATCH = 4096
#: Distance of the far coupler point from the crank pin, in crank lengths.
FAR_POINT = 1e6


def _log_uniform(rng, lo, hi, n):
    return np.exp(rng.uniform(np.log(lo), np.log(hi), n))


def _reachable_angles(rng, a, b, c, d):
    """A crank angle where the loop closes (cos φ inside its window), or any angle if none."""
    hi = np.minimum((a * a + d * d - (b - c) ** 2) / (2 * a * d), 1.0)
    lo = np.maximum((a * a + d * d - (b + c) ** 2) / (2 * a * d), -1.0)
    ok = lo <= hi
    cos_phi = np.where(ok, rng.uniform(0, 1, a.size) * (hi - lo) + lo, rng.uniform(-1, 1, a.size))
    return np.arccos(np.clip(cos_phi, -1, 1)) * rng.choice([-1.0, 1.0], a.size), lo, hi, ok


def make_cases(n: int, seed: int) -> dict[str, np.ndarray]:
    """Flat arrays a, b, c, d, branch, phi and ``family`` (index into FAMILIES) for n cases."""
    rng = np.random.default_rng(seed)
    counts = np.bincount(rng.integers(0, len(FAMILIES), n), minlength=len(FAMILIES))
    branch = rng.choice([-1.0, 1.0], n)  # in family order, like the parts below
    parts = []

    # random ratios
    k = counts[0]
    b, c, d = (_log_uniform(rng, 1e-3, 1e3, k) for _ in range(3))
    a = np.ones(k)
    phi, *_ = _reachable_angles(rng, a, b, c, d)
    parts.append((a, b, c, d, phi))

    # change point: s + l = p + q, then one link ± 1e-12 relative
    k = counts[1]
    p, q = _log_uniform(rng, 0.1, 10, k), _log_uniform(rng, 0.1, 10, k)
    s = rng.uniform(0.05, 0.95, k) * np.minimum(p, q)
    links = np.stack([s, p + q - s, p, q], axis=1)
    links[:, 1] *= 1 + rng.choice([-1e-12, 1e-12], k)
    links = np.take_along_axis(links, np.argsort(rng.random((k, 4)), axis=1), axis=1)
    links /= links[:, :1]
    a, b, c, d = links.T
    phi, *_ = _reachable_angles(rng, a, b, c, d)
    flat = rng.random(k) < 1 / 3
    phi = np.where(flat, rng.choice([0.0, np.pi], k) + rng.uniform(-1e-9, 1e-9, k), phi)
    parts.append((a, b, c, d, phi))

    # near toggle: the crank cannot turn fully; φ within 1e-9 rad of a limit of its range
    k = counts[2]
    got = [tuple(np.empty(0) for _ in range(5))]  # a small --n may draw no case of this family
    while sum(x[0].size for x in got) < k:
        b, c, d = (_log_uniform(rng, 0.05, 20, 4 * k + 8) for _ in range(3))
        a = np.ones_like(b)
        _, lo, hi, ok = _reachable_angles(rng, a, b, c, d)
        limited = ok & ((lo > -1) | (hi < 1))
        a, b, c, d, lo, hi = (x[limited] for x in (a, b, c, d, lo, hi))
        edge = np.where(
            (hi < 1) & ((lo <= -1) | (rng.random(a.size) < 0.5)),
            np.arccos(np.clip(hi, -1, 1)),
            np.arccos(np.clip(lo, -1, 1)),
        )
        eps = rng.uniform(0, 1e-9, a.size)
        for sign in (1.0, -1.0):
            phi = edge + sign * eps
            inside = fourbar_motion(a, b, c, d, phi, 1, order=0).status == 0
            got.append((a[inside], b[inside], c[inside], d[inside], phi[inside]))
            a, b, c, d, edge, eps = (x[~inside] for x in (a, b, c, d, edge, eps))
    parts.append(tuple(np.concatenate([x[i] for x in got])[:k] for i in range(5)))

    # near translation: θ′ = 0 located by bisection, then ± 1e-9 rad
    k = counts[3]
    a, b, c, d = crank_rockers(k, int(rng.integers(2**31)))
    br = branch[counts[:3].sum() : counts[:4].sum()]
    grid = np.linspace(0, 2 * np.pi, 65)
    t1 = fourbar_motion(a[:, None], b[:, None], c[:, None], d[:, None], grid, br[:, None], order=1).dtheta[0]
    j = np.argmax(np.sign(t1[:, :-1]) != np.sign(t1[:, 1:]), axis=1)
    lo, hi = grid[j], grid[j + 1]
    s_lo = np.sign(t1[np.arange(k), j])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        same = np.sign(fourbar_motion(a, b, c, d, mid, br, order=1).dtheta[0]) == s_lo
        lo, hi = np.where(same, mid, lo), np.where(same, hi, mid)
    parts.append((a, b, c, d, 0.5 * (lo + hi) + rng.uniform(-1e-9, 1e-9, k)))

    # ordinary crank-rockers
    k = counts[4]
    a, b, c, d = crank_rockers(k, int(rng.integers(2**31)))
    parts.append((a, b, c, d, rng.uniform(0, 2 * np.pi, k)))

    cols = [np.concatenate([p[i] for p in parts]) for i in range(5)]
    family = np.repeat(np.arange(len(FAMILIES)), [p[0].size for p in parts])
    return {
        "a": cols[0],
        "b": cols[1],
        "c": cols[2],
        "d": cols[3],
        "branch": branch,
        "phi": cols[4],
        "family": family,
        "ray_offsets": rng.uniform(-1e-12, 1e-12, (family.size, 4)),
        "ray_random": rng.uniform(0, np.pi, (family.size, 2)),
        "beta": rng.uniform(0, 2 * np.pi, (family.size, 4)),
    }


def evaluate_cases(case: dict[str, np.ndarray]) -> dict[str, object]:
    """All kernels on a batch of cases (columns of shape (n, 1)); results by kind."""
    col = {k: v[:, None] if v.ndim == 1 else v for k, v in case.items()}
    motion = fourbar_motion(col["a"], col["b"], col["c"], col["d"], col["phi"], col["branch"], order=3)
    pl = pole(motion)
    circle = inflection_circle(pl)
    ball = ball_point(pl)
    tangent = np.angle(pl.tangent)
    normal = np.angle(pl.normal)
    alpha = np.concatenate(
        [col["ray_random"], tangent + col["ray_offsets"][:, :2], normal + col["ray_offsets"][:, 2:]], axis=1
    )
    scan = line_scan(pl, alpha)
    beta = col["beta"]
    size = np.maximum(np.maximum(col["a"], col["b"]), np.maximum(col["c"], col["d"]))
    # coupler points (coupler frame): one a linkage size from A, one FAR_POINT cranks away
    points = np.concatenate([size * np.exp(1j * beta[:, :1]), FAR_POINT * col["a"] * np.exp(1j * beta[:, 1:2])], axis=1)
    centres = euler_savary(pl, pl.to_fixed(points))
    return {
        "motion": motion,
        "pole": pl,
        "inflection_circle": circle,
        "ball_point": ball,
        "line_scan": scan,
        "euler_savary": centres,
        "points": points,
    }


def _nonfinite(results: dict[str, object]) -> int:
    count = 0
    for kind, res in results.items():
        if kind in ("motion", "points"):
            continue
        for name in res.__slots__:
            value = getattr(res, name)
            for arr in value if isinstance(value, tuple) else (value,):
                arr = np.asarray(arr)
                if arr.dtype.kind in "fc":
                    count += int(np.count_nonzero(~np.isfinite(arr)))
    return count


def _residuals(case: dict[str, np.ndarray], r: dict[str, object]) -> dict[str, np.ndarray]:
    """Residuals (see module notes) of the unflagged results of one batch, by kind."""
    col = {k: v[:, None] if v.ndim == 1 else v for k, v in case.items()}
    jet = reference.loop_jet(col["a"], col["b"], col["c"], col["d"], col["branch"], col["phi"])
    return reference.residuals(jet, col["a"], r, circle_angles=col["beta"][:, 2:])


def stability_summary(n: int, seed: int = 0) -> dict:
    """Run n cases and summarise flags, non-finite values, exceptions and residuals."""
    t0 = time.perf_counter()
    cases = make_cases(n, seed)
    kinds = ("pole", "inflection_circle", "ball_point", "line_scan", "euler_savary")
    flagged = {k: {} for k in kinds}
    by_family = {f: {"items": dict.fromkeys(kinds, 0), "flagged": dict.fromkeys(kinds, 0)} for f in FAMILIES}
    items = dict.fromkeys(kinds, 0)
    unflagged = dict.fromkeys(kinds, 0)
    worst = {
        k: 0.0 for k in ("pole", "inflection_circle", "ball_point", "circle_point", "center_point", "euler_savary")
    }
    exceptions: dict[str, int] = {}
    nonfinite = 0
    for i in range(0, n, BATCH):
        batch = {k: v[i : i + BATCH] for k, v in cases.items()}
        try:
            results = evaluate_cases(batch)
        except Exception:  # noqa: BLE001 — counted case by case below, never fatal
            results = None
            for j in range(batch["a"].size):
                try:
                    evaluate_cases({k: v[j : j + 1] for k, v in batch.items()})
                except Exception as exc:  # noqa: BLE001
                    name = type(exc).__name__
                    exceptions[name] = exceptions.get(name, 0) + 1
        if results is None:
            continue
        nonfinite += _nonfinite(results)
        for kind in kinds:
            status = np.asarray(results[kind].status)
            items[kind] += status.size
            unflagged[kind] += int(np.count_nonzero(status == 0))
            per_case = status.reshape(status.shape[0], -1)
            for k, f in enumerate(FAMILIES):
                rows = per_case[batch["family"] == k]
                by_family[f]["items"][kind] += rows.size
                by_family[f]["flagged"][kind] += int(np.count_nonzero(rows))
            for flag in Status:
                if flag:
                    hits = int(np.count_nonzero(status & flag))
                    if hits:
                        key = flag.name.lower()
                        flagged[kind][key] = flagged[kind].get(key, 0) + hits
        with np.errstate(all="ignore"):
            res = _residuals(batch, results)
        for name, values in res.items():
            if values.size:
                worst[name] = max(worst[name], float(np.max(values)))
    raising = _raise_mode_check(cases)
    return {
        "benchmark": "stability",
        "cases": n,
        "seed": seed,
        "families": {f: int(np.count_nonzero(cases["family"] == k)) for k, f in enumerate(FAMILIES)},
        "items": items,
        "unflagged": unflagged,
        "flagged": flagged,
        "by_family": by_family,
        "nonfinite_values": nonfinite,
        "exceptions": exceptions,
        "raise_mode": raising,
        "max_residual_unflagged": worst,
        "max_residual_unflagged_overall": max(worst.values()),
        "residual_norm": "distance / max(crank, distance of the point from the crank pin); centres / max(crank, radius)",
        "seconds": round(time.perf_counter() - t0, 3),
    }


def _raise_mode_check(cases: dict[str, np.ndarray], count: int = 200) -> dict[str, int]:
    """on_degenerate="raise" on the first cases: only the documented AssemblyError may escape."""
    out = {"cases": 0, "assembly_error": 0, "other_exceptions": 0}
    for j in range(min(count, cases["a"].size)):
        out["cases"] += 1
        try:
            motion = fourbar_motion(
                *(cases[k][j] for k in ("a", "b", "c", "d", "phi", "branch")), on_degenerate="raise"
            )
            pl = pole(motion, on_degenerate="raise")
            inflection_circle(pl, on_degenerate="raise")
            ball_point(pl, on_degenerate="raise")
            line_scan(pl, cases["ray_random"][j], on_degenerate="raise")
        except AssemblyError:
            out["assembly_error"] += 1
        except Exception:  # noqa: BLE001
            out["other_exceptions"] += 1
    return out


@click.command("stability")
@click.option(
    "--n", "n_cases", type=click.IntRange(1, 10_000_000), default=100_000, show_default=True, help="Number of cases."
)
@click.option("--seed", type=SEED, default=0, show_default=True, help="Seed of the random cases (>= 0).")
def stability(n_cases: int, seed: int) -> None:
    """Random and adversarial cases: flags per reason, NaN/inf, exceptions, residuals (JSON)."""
    click.echo(json.dumps(stability_summary(n_cases, seed), indent=1))
