"""The hand's environment port seen through its sensors: work the finger pads do on the object.

The two-layer hand side (``controller.ports.hand_port = "object"``) pays from its tank for the
work its fingers do on the environment, estimated from what the hand measures at 40 Hz: the
tactile cells (force and where it acts) and the link angles (how far the pads moved along their
normals).  The servo's work on the finger's own springs, tendon and friction stays inside the
hand and is not the environment's business; what of it could still reach the object is held
back as a reservation (:func:`teleop.control.passivity_layer.reservation_j`).

Sensor model (a calibration of the TakkTile cells, not the simulator): a normal force ``F``
acting at ``x`` along a link reads ``g F k(x_i - x)`` on the cell at ``x_i``, with the kernel
``k(d) = exp(-d^2 / 2 s^2) + a exp(-|d| / l)``.  The contact position is the point of the pad
whose kernel pattern best fits the readings (least squares, the force free), the force the one
that fits there.

Pad motion along the contact normal over one sample (``dtp``, ``dtd``: changes of the proximal
and distal angles; ``L``: base axle to flexure; ``t_d``: distal bend)::

    proximal pad at r:  ds = r dtp
    distal pad at r:    ds = (L cos t_d + r) dtp + r dtd

Work ``F ds`` per sample with the force taken on the safe side: ``max(F(k-1), F(k))`` while
the pad moves into the object, ``min(F(k-1), F(k))`` while it backs out.  These add up to the
estimated net work on the object ``W``; the tank has paid ``m W`` for it while ``W >= 0`` and
``W / m`` while the object has given back more than it got (:func:`margin_charge_j`): a force
gain error within ``[1/m, m]`` scales the whole estimate, so this stays on the safe side at
every sample, and an elastic squeeze that gives back what it took costs nothing but the
sampling terms (a per-sample margin would charge ``(m - 1/m)`` of the elastic energy on every
squeeze).

Encoder noise ``n``: the work estimated from noisy angles differs from the true work by
``int F dn = [F n] - int n dF``; for noise that is zero-mean and independent of the contact
force this averages out (an assumption, stated in docs/controllers.md; measured on the
simulated hand's encoders it costs a few mJ per grasp through the max/min rule).  A deadband
(play) filter on the angles, with what it can hide charged (``b r |dF|`` per sample) and held
back (``m b r F``), was tried and dropped: measured, its charges cost more than the noise it
removes.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from teleop.frozen import fast_init
from teleop.messages import FingerState


@dataclass(frozen=True, slots=True)
class TactileModel:
    """What the hand side knows about its tactile cells and finger geometry."""

    pressure_per_n: float = 100.0
    proximal_sensor_x_m: tuple[float, ...] = (0.0189, 0.0268, 0.0347, 0.0426, 0.0506)
    distal_sensor_x_m: tuple[float, ...] = (0.0114, 0.0193, 0.0272, 0.0375)
    kernel_sigma_m: float = 0.004
    kernel_tail: float = 0.08
    kernel_tail_m: float = 0.010
    proximal_length_m: float = 0.076
    proximal_pad_m: tuple[float, float] = (0.010, 0.060)
    distal_pad_m: tuple[float, float] = (0.0, 0.045)
    noise_floor: float = 6.0
    force_margin: float = 1.15
    yield_window_m: float = 0.001
    yield_stiffness_ratio: float = 0.2
    yield_set_check: bool = True
    yield_credit: bool = True
    stall_window_rad: float = 0.1
    stall_ratio: float = 0.3
    free_curl_rad: float = 0.45
    load_torque_nm_per_unit: float = 0.00347
    base_spring_nm_per_rad: float = 0.0624
    base_preload_rad: float = 1.957
    gain_check_window_s: float = 0.2
    gain_check_still_rad: float = 0.02
    gain_check_damping_nm_s_per_rad: float = 4.5
    gain_check_tolerance_nm: float = 0.15


@fast_init
@dataclass(frozen=True, slots=True)
class PadTrack:
    """One finger's tracked contact: last angles, forces and positions."""

    proximal_rad: float
    distal_rad: float
    prox_force_n: float = 0.0
    prox_x_m: float = 0.0
    dist_force_n: float = 0.0
    dist_x_m: float = 0.0


def kernel(model: TactileModel, d_m: float) -> float:
    """One cell's reading per unit force ``d_m`` away from it (over the gain)."""
    s = model.kernel_sigma_m
    return math.exp(-0.5 * d_m * d_m / (s * s)) + model.kernel_tail * math.exp(
        -abs(d_m) / model.kernel_tail_m)


@functools.lru_cache(maxsize=16)
def _kernel_table(model: TactileModel, xs: tuple[float, ...], lo_m: float, hi_m: float,
                  step_m: float = 2.5e-4) -> tuple[tuple[float, tuple[float, ...], float], ...]:
    """For contact positions every ``step_m`` along the pad: (position, the cells' kernel
    values, their squared norm)."""
    n = max(2, int(round((hi_m - lo_m) / step_m)) + 1)
    rows = []
    for i in range(n):
        x = lo_m + (hi_m - lo_m) * i / (n - 1)
        ks = tuple(kernel(model, xk - x) for xk in xs)
        rows.append((x, ks, sum(k * k for k in ks)))
    return tuple(rows)


#: how far a tracked contact point may move along its pad between two samples (12 cm/s)
TRACK_STEP_M = 0.003


def contact_estimate(model: TactileModel, cells: tuple[float, ...], xs: tuple[float, ...],
                     pad_m: tuple[float, float] | None = None,
                     near_m: float | None = None) -> tuple[float, float]:
    """``(force N, position m)`` of the contact on one link from its cells (0 force: none):
    the position along the pad whose kernel pattern fits the readings best (least squares
    with the force free, positions every 0.25 mm), then the force that fits at it.  Positions
    past the end cells (up to the pad's ends ``pad_m``) only when the peak reading is at
    least four noise floors.  ``near_m``: the contact's last position; the fit then looks
    within ``TRACK_STEP_M`` of it (a contact point slides, it does not jump: without this a
    weak pattern's fit hops along the pad and the force estimate with it)."""
    p = [max(v, 0.0) if math.isfinite(v) else 0.0 for v in cells]
    if not p or len(p) != len(xs) or max(p) <= model.noise_floor:
        return 0.0, 0.0
    # past the end cells only with a clear signal: a weak, noisy pattern fitted out there
    # would read as a large force (the kernel is small far from every cell)
    strong = pad_m is not None and max(p) >= 4.0 * max(model.noise_floor, 1.0)
    table = _kernel_table(model, xs, *(pad_m if strong and pad_m is not None
                                       else (xs[0], xs[-1])))
    rows: Sequence[tuple[float, tuple[float, ...], float]] = table
    if near_m is not None and near_m > 0.0:
        rows = _near_rows(table, near_m) or table
    return _best_fit(p, rows, model.pressure_per_n)


def _near_rows(table: tuple[tuple[float, tuple[float, ...], float], ...], near_m: float
               ) -> tuple[tuple[float, tuple[float, ...], float], ...]:
    """The rows with ``abs(x - near_m) <= TRACK_STEP_M + 1e-12``, in table order.

    The table's positions rise with the row (``lo + (hi - lo) * i / (n - 1)``: each float
    operation is monotone), so ``x - near_m`` does too and the rows passing the test are one
    run: found by bisection on the test's own two comparisons (``-reach <= d <= reach``, the
    same as ``abs(d) <= reach``), not by testing every row."""
    reach = TRACK_STEP_M + 1e-12
    if not table[0][0] <= table[-1][0]:  # (falling: a pad given high end first) test each row
        return tuple(r for r in table if abs(r[0] - near_m) <= reach)
    lo = bisect.bisect_left(table, -reach, key=lambda r: r[0] - near_m)
    hi = bisect.bisect_right(table, reach, lo, key=lambda r: r[0] - near_m)
    return table[lo:hi]


def _best_fit(p: list[float], rows: Sequence[tuple[float, tuple[float, ...], float]],
              pressure_per_n: float) -> tuple[float, float]:
    """``(force N, position m)`` of the row whose kernel pattern fits ``p`` best (the first of
    equal scores).  The cell sums are written out for the pads' four and five cells:
    ``0.0 + a0 b0 + a1 b1 + ...`` left to right is what ``sum`` of the products adds (from
    the int 0), so the same floats."""
    best_s, best_x, best_scale = -1.0, 0.0, 0.0
    if len(p) == 5:
        p0, p1, p2, p3, p4 = p
        for x, (k0, k1, k2, k3, k4), kk in rows:
            pk = 0.0 + p0 * k0 + p1 * k1 + p2 * k2 + p3 * k3 + p4 * k4
            score = pk * pk / kk  # |p|^2 minus the residual of the best fit at x
            if score > best_s:
                best_s, best_x, best_scale = score, x, pk / kk
    elif len(p) == 4:
        p0, p1, p2, p3 = p
        for x, (k0, k1, k2, k3), kk in rows:
            pk = 0.0 + p0 * k0 + p1 * k1 + p2 * k2 + p3 * k3
            score = pk * pk / kk
            if score > best_s:
                best_s, best_x, best_scale = score, x, pk / kk
    else:
        for x, ks, kk in rows:
            pk = sum([a * b for a, b in zip(p, ks, strict=True)])
            score = pk * pk / kk
            if score > best_s:
                best_s, best_x, best_scale = score, x, pk / kk
    return best_scale / pressure_per_n, best_x


def _split(model: TactileModel, pressure: tuple[float, ...]
           ) -> tuple[tuple[float, ...], tuple[float, ...]]:
    n = len(model.proximal_sensor_x_m)
    m = len(model.distal_sensor_x_m)
    cells = tuple(pressure) + (0.0,) * max(0, n + m - len(pressure))
    return cells[:n], cells[n:n + m]


def _safe_work(f0: float, f1: float, ds: float) -> tuple[float, float]:
    """(into, back) J for a pad that moved ``ds`` into the object between two samples: the
    larger force for a move in, the smaller for a move out."""
    if ds > 0.0:
        return max(f0, f1) * ds, 0.0
    return 0.0, min(f0, f1) * (-ds)


def margin_charge_j(model: TactileModel, net_j: float) -> float:
    """What the tank has paid for an estimated net work ``net_j`` on the object so far:
    ``m net`` while the object has received more than it gave back, ``net / m`` while it has
    given more (the sensor's gain error, within ``[1/m, m]``, scales the whole estimate)."""
    m = model.force_margin
    return m * net_j if net_j >= 0.0 else net_j / m


def track_start(f: FingerState) -> PadTrack:
    """The first sample of a finger: angles as read, no force yet (nothing charged)."""
    p = f.proximal_rad if math.isfinite(f.proximal_rad) else 0.0
    d = f.distal_rad if math.isfinite(f.distal_rad) else 0.0
    return PadTrack(proximal_rad=p, distal_rad=d)


def track_finger(model: TactileModel, prev: PadTrack,
                 f: FingerState) -> tuple[PadTrack, float, float]:
    """One hand sample of one finger: ``(track, into J, back J)``, the sampling-safe
    estimates (before the margin) of the work its pads did on the object and the object did
    on them (both >= 0)."""
    pp, pd = _split(model, f.pressure)
    fp1, rp1 = contact_estimate(model, pp, model.proximal_sensor_x_m, model.proximal_pad_m,
                                prev.prox_x_m if prev.prox_force_n > 0.0 else None)
    fd1, rd1 = contact_estimate(model, pd, model.distal_sensor_x_m, model.distal_pad_m,
                                prev.dist_x_m if prev.dist_force_n > 0.0 else None)
    tp1 = f.proximal_rad if math.isfinite(f.proximal_rad) else prev.proximal_rad
    td1 = f.distal_rad if math.isfinite(f.distal_rad) else prev.distal_rad
    dtp, dtd = tp1 - prev.proximal_rad, td1 - prev.distal_rad
    fp0, rp0, fd0, rd0 = prev.prox_force_n, prev.prox_x_m, prev.dist_force_n, prev.dist_x_m
    out_j = in_j = 0.0
    if fp0 > 0.0 or fp1 > 0.0:
        rs = [r for r, fo in ((rp0, fp0), (rp1, fp1)) if fo > 0.0]
        c, t = _safe_work(fp0, fp1, max(r * dtp for r in rs))
        out_j, in_j = out_j + c, in_j + t
    if fd0 > 0.0 or fd1 > 0.0:
        rs = [r for r, fo in ((rd0, fd0), (rd1, fd1)) if fo > 0.0]
        lever = model.proximal_length_m * math.cos(0.5 * (prev.distal_rad + td1))
        # the safe side of the two lever arms: the larger move in, the smaller move out
        ds = max((lever + r) * dtp + r * dtd for r in rs)
        c, t = _safe_work(fd0, fd1, ds)
        out_j, in_j = out_j + c, in_j + t
    track = PadTrack(proximal_rad=tp1, distal_rad=td1, prox_force_n=fp1, prox_x_m=rp1,
                     dist_force_n=fd1, dist_x_m=rd1)
    return track, out_j, in_j


def margin_net_j(model: TactileModel, charged_j: float) -> float:
    """The inverse of :func:`margin_charge_j`: the net work a total charge stands for."""
    m = model.force_margin
    return charged_j / m if charged_j >= 0.0 else charged_j * m


def track_fingers(model: TactileModel, prev: tuple[PadTrack, ...] | None,
                  fingers: tuple[FingerState, ...]
                  ) -> tuple[tuple[PadTrack, ...], tuple[tuple[float, float], ...]]:
    """All fingers: ``(tracks, ((into J, back J) per finger))`` (both 0 at the first
    sample)."""
    if prev is None or len(prev) != len(fingers):
        return tuple(track_start(f) for f in fingers), tuple((0.0, 0.0) for _ in fingers)
    tracks = []
    works = []
    for t0, f in zip(prev, fingers, strict=True):
        t1, o, i = track_finger(model, t0, f)
        tracks.append(t1)
        works.append((o, i))
    return tuple(tracks), tuple(works)
