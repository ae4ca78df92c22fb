"""The volume edge along drill paths: where the cutting lip's data end (closed form, any N).

The CT's data are its voxel-centre hull: ``0 <= i, j <= n - 1`` and the first to the last real
slice, a parallelepiped in LPS (six face planes ``f(p) = alpha . p + beta >= 0`` in affine
index units). The drill's cutting lip (DESIGN.md 1.4) at tip depth ``x`` is the cone from the
tip (radius 0, depth ``x``) to the rim (radius ``R``, depth ``x - l_t``).

**The entry rule.** Depth 0 is the entry point. Only the part of the lip at or ahead of the
entry is in contact with what the drill cuts (the paper's ``s_t`` counts the lip in contact):
at tip depth ``x`` that is the rings of radius ``r <= R min(1, x / l_t)`` (the whole lip from
``x = l_t`` on; only the tip point at ``x = 0``). So an entry inside the scan is never refused
because the part of the drill *behind* the entry (the shoulder, the shank) leaves the scan;
the lip is sampled there as everywhere (outside the scan it reads as air, AIR_HU). A path
stops at the first tip depth where the lip in contact leaves the hull
(:func:`lip_exit_depths`). An entry outside the hull is refused with a message naming the
part of the drill outside, the tip depths it stays outside and how far the entry must move
(:func:`entry_refusal`).

Along a face plane the lip's smallest value at depth ``x`` is
``a + x b + min(1, x / l_t) c`` with ``a`` the value at the entry, ``b = alpha . u`` and
``c = min(0, -l_t b - R |alpha_perp|) <= 0`` (the minimum over the ring angle is
``-r |alpha_perp|``, linear in ``r``): linear on ``[0, l_t]`` and on ``[l_t, inf)``, so the
exit depth is exact, not bisected.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ctdrill.imaging.plan.types import DrillSpec
from ctdrill.imaging.volume import CTVolume

#: How far outside a face an entry may lie and still count as inside, affine index units
#: (the sampler's own hull tolerance, :meth:`CTVolume.inside`).
EDGE_TOL_VOX = 1e-6
#: Below this slope (index units per mm) a face is parallel to the axis.
_FLAT = 1e-15
#: The faces in the order of the constraint columns: (index axis, lower or upper face).
_FACES = tuple(itertools.product(range(3), ("lower", "upper")))
_FACE_WORDS = {
    (0, "lower"): "before the first column",
    (0, "upper"): "beyond the last column",
    (1, "lower"): "before the first row",
    (1, "upper"): "beyond the last row",
    (2, "lower"): "before the first slice",
    (2, "upper"): "beyond the last slice",
}


def index_planes(volume: CTVolume) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows ``a_m``, offsets ``c_m`` with affine index ``m = a_m . p + c_m``, and the hull's
    upper bounds in those units (the true last slice for k)."""
    cols, rows, _ = volume.dims
    k_top = float(volume.affine_slice_index[-1])
    # the volume's own inverse of its affine (np.linalg.inv of affine_lps, kept)
    return volume._inv_lin, volume._inv_off, np.array([cols - 1.0, rows - 1.0, k_top])


def axis_frames(entries_lps: np.ndarray, targets_lps: np.ndarray) -> np.ndarray:
    """(N, 3, 3) :func:`~ctdrill.imaging.sampling.lip.axis_basis` of every row, vectorised
    (equal to it to rounding; rows with entry == target give NaN)."""
    d = np.asarray(targets_lps, dtype=np.float64) - np.asarray(entries_lps, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        axis = d / np.sqrt(np.sum(d * d, axis=1))[:, None]
        helper = np.zeros_like(axis)
        helper[np.arange(len(axis)), np.argmin(np.abs(axis), axis=1)] = 1.0
        e1 = helper - np.sum(helper * axis, axis=1)[:, None] * axis
        e1 /= np.sqrt(np.sum(e1 * e1, axis=1))[:, None]
    e2 = np.empty_like(axis)  # axis x e1, written out (np.cross costs more than the rest)
    e2[:, 0] = axis[:, 1] * e1[:, 2] - axis[:, 2] * e1[:, 1]
    e2[:, 1] = axis[:, 2] * e1[:, 0] - axis[:, 0] * e1[:, 2]
    e2[:, 2] = axis[:, 0] * e1[:, 1] - axis[:, 1] * e1[:, 0]
    return np.stack([axis, e1, e2], axis=1)


@dataclass(frozen=True, eq=False)
class FaceTerms:
    """Each row's six face constraints ``g(x) = a + x b + min(1, x / l_t) c >= 0``.

    Attributes
    ----------
    a, b, c : (N, 6) in affine index units (per mm for ``b``), faces in :data:`_FACES` order.
    scale : (6,) mm per index unit across each face (``1 / |alpha|``).
    tip_length_mm : the drill's ``l_t``.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    scale: np.ndarray
    tip_length_mm: float

    def at_entry(self) -> np.ndarray:
        """(N, 6) the constraints at depth 0 (the tip alone; the flat lip of ``l_t = 0``)."""
        return self.a + (self.c if self.tip_length_mm <= 0.0 else 0.0)


def face_terms(
    volume: CTVolume, entries_lps: np.ndarray, targets_lps: np.ndarray, drill: DrillSpec
) -> FaceTerms:
    """The lip's face constraints of ``N`` trajectories (see the module docstring)."""
    lin, off, top = index_planes(volume)
    entries = np.asarray(entries_lps, dtype=np.float64).reshape(-1, 3)
    basis = axis_frames(entries, np.asarray(targets_lps, dtype=np.float64).reshape(-1, 3))
    n = entries.shape[0]
    a, b, c = (np.empty((n, 6)) for _ in range(3))
    lt, radius = float(drill.tip_length_mm), float(drill.radius_mm)
    for m in range(3):
        su = basis[:, 0] @ lin[m]
        w = np.hypot(basis[:, 1] @ lin[m], basis[:, 2] @ lin[m])
        value = entries @ lin[m]
        # lower face: value + off + x su + rho low >= 0; upper: top - (value + off) - ... >= 0
        a[:, 2 * m] = value + off[m]
        b[:, 2 * m] = su
        c[:, 2 * m] = np.minimum(0.0, -lt * su - radius * w)
        a[:, 2 * m + 1] = top[m] - value - off[m]
        b[:, 2 * m + 1] = -su
        c[:, 2 * m + 1] = -np.maximum(0.0, -lt * su + radius * w)
    scale = np.repeat(1.0 / np.linalg.norm(lin, axis=1), 2)
    return FaceTerms(a, b, c, scale, lt)


def lip_exit_depths(terms: FaceTerms) -> tuple[np.ndarray, np.ndarray]:
    """Which entries lie in the hull, and where the lip in contact first leaves it.

    Returns
    -------
    inside : (N,) bool, the entry (with the flat lip of a drill without a tip cone) lies in
        the hull, to :data:`EDGE_TOL_VOX`.
    exit_mm : (N,) the first tip depth at which the lip in contact leaves the hull, mm (inf:
        never); meaningful where ``inside``.
    """
    lt = terms.tip_length_mm
    a, b, c = terms.a, terms.b, terms.c
    inside = np.all(terms.at_entry() >= -EDGE_TOL_VOX, axis=1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # from l_t on (the whole lip): a + c + x b >= 0 (the closed form of the whole lip)
        whole = np.where(np.abs(b) < _FLAT, np.inf, -(a + c) / b)
        whole = np.where((np.abs(b) >= _FLAT) & (b < 0.0), whole, np.inf)
        if lt > 0.0:  # on [0, l_t] the rings in contact grow: a + x (b + c / l_t) >= 0
            slope = b + c / lt
            early = np.where(slope < 0.0, np.maximum(a, 0.0) / -slope, np.inf)
            exit_face = np.where(early < lt, early, whole)
        else:
            exit_face = whole
    return inside, np.min(exit_face, axis=1, initial=np.inf)


def whole_lip_fits(terms: FaceTerms) -> np.ndarray:
    """(N,) bool: some tip depth along the axis has the whole lip (rim at radius ``R``)
    inside the hull. False: the drill is wider than the scan across its axis; no depth of its
    path can be sampled whole, and the path is refused (a lip read as air there would pass for
    a drill cutting nothing)."""
    a, b, c = terms.a, terms.b, terms.c
    value = a + c  # the whole lip at depth 0, per face; at depth x: value + x b >= 0
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = -value / b
    flat = np.abs(b) < _FLAT
    lo = np.max(np.where(~flat & (b > 0.0), bound, -np.inf), axis=1, initial=-np.inf)
    hi = np.min(np.where(~flat & (b < 0.0), bound, np.inf), axis=1, initial=np.inf)
    flat_ok = np.all(~flat | (value >= -EDGE_TOL_VOX), axis=1)
    return np.asarray(flat_ok & (lo <= hi + EDGE_TOL_VOX))


def too_wide_refusal(volume: CTVolume, drill: DrillSpec, *, name: str = "") -> str:
    """The refusal of a drill whose whole lip fits nowhere along its axis in the scan."""
    cols, rows, slices = volume.dims
    sx, sy, sz = volume.spacing_mm
    where = f"plan {name!r}: " if name else ""
    return (
        f"{where}the drill ({drill.diameter_mm:g} mm) is wider than the scan around its axis "
        f"(the CT spans {cols * sx:.1f} x {rows * sy:.1f} x {slices * sz:.1f} mm): at no depth "
        "along the axis does its whole cutting lip lie inside the CT, so no force can be "
        "computed; choose a narrower drill, an axis farther from the scan's edges or a larger "
        "scan"
    )


def _nearest_inside(volume: CTVolume, entry_lps: np.ndarray) -> np.ndarray:
    """(3,) the point of the hull nearest ``entry_lps`` (LPS mm), exact: the box in affine
    index space under the affine's metric, every active set tried."""
    lin, off, top = index_planes(volume)
    q0 = lin @ entry_lps + off
    to_lps = np.linalg.inv(lin)
    g = to_lps.T @ to_lps  # |dp|^2 = dq^T g dq
    best, best_q = math.inf, np.clip(q0, 0.0, top)
    for state in itertools.product((None, 0.0, 1.0), repeat=3):
        q = q0.copy()
        fixed = [m for m in range(3) if state[m] is not None]
        free = [m for m in range(3) if state[m] is None]
        for m in fixed:
            q[m] = 0.0 if state[m] == 0.0 else top[m]
        if free:
            dq_fixed = q[fixed] - q0[fixed]
            rhs = -g[np.ix_(free, fixed)] @ dq_fixed
            q[free] = q0[free] + np.linalg.solve(g[np.ix_(free, free)], rhs)
        if np.any(q < -1e-12) or np.any(q > top + 1e-12):
            continue
        dq = q - q0
        value = float(dq @ g @ dq)
        if value < best:
            best, best_q = value, q
    return np.asarray(to_lps @ (best_q - off))


def _mm(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def entry_refusal(
    volume: CTVolume,
    entry_lps: np.ndarray,
    target_lps: np.ndarray,
    drill: DrillSpec,
    *,
    name: str = "",
) -> str:
    """The refusal of an entry outside the scan: which part of the drill is outside at depth
    0 and by how much, at which tip depths the tip stays outside, how far the entry must move.
    """
    entry = np.asarray(entry_lps, dtype=np.float64)
    terms = face_terms(volume, entry[None], np.asarray(target_lps)[None], drill)
    g0 = terms.at_entry()[0]
    tip_out = terms.a[0] < -EDGE_TOL_VOX
    where = f"plan {name!r}: " if name else ""
    sides = [
        f"{_mm(-terms.a[0, f] * terms.scale[f])} mm {_FACE_WORDS[_FACES[f]]}"
        for f in range(6)
        if tip_out[f]
    ]
    point = np.round(entry, 2).tolist()
    if not sides:  # a drill without a tip cone: its flat lip at depth 0 pokes out
        sides = [
            f"{_mm(-g0[f] * terms.scale[f])} mm {_FACE_WORDS[_FACES[f]]}"
            for f in range(6)
            if g0[f] < -EDGE_TOL_VOX
        ]
        return (
            f"{where}the flat lip of the drill (no tip cone: its whole rim, radius "
            f"{_mm(drill.radius_mm)} mm, cuts from depth 0) at the entry point {point} (LPS mm) "
            f"lies outside the CT volume, {' and '.join(sides)}; move the entry inside the "
            "scanned field by at least that much, or plan with the drill's tip length"
        )
    a, b = terms.a[0], terms.b[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        enters = np.where(b > _FLAT, -a / b, np.inf)
    never = bool(np.any(tip_out & (b <= _FLAT)))
    depth_in = float(np.max(np.where(tip_out, enters, 0.0)))
    along = (
        "the tip never enters the scan along this axis"
        if never
        else f"along the axis the tip stays outside the scan for tip depths 0 to {_mm(depth_in)} mm"
    )
    near = _nearest_inside(volume, entry)
    move = float(np.linalg.norm(near - entry))
    return (
        f"{where}the entry point {point} (LPS mm) lies outside the CT volume: the drill tip at "
        f"depth 0 is {' and '.join(sides)} of the scan; {along}; move the entry at least "
        f"{_mm(move)} mm into the scanned field (the nearest point inside is "
        f"{np.round(near, 2).tolist()}); only the lip ahead of the entry must lie in the scan"
    )
