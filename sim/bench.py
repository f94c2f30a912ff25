"""``teleop bench sim``: how much faster than real time the finger and hand models run.

Scenario: a 1 kHz position controller (a 0.5 Hz sine of the joint set-point between 0 and
1.4 rad) drives one finger against the default cylinder (so contact is part of the run), with
the physics stepped once per controller tick (dt = 1 ms).  The hand figure runs the same
controller on all three fingers plus the preshape joint through :func:`sim.hand.hand_step`.

The compiled comparison times the same arithmetic in C: a tiny C program with the same
per-step operation count (geometry of a 4-segment flexure, two pad contacts, the implicit
tendon solve) is compiled with gcc at bench time when gcc exists; otherwise the figure is
omitted and the reasoning is in the README.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import tempfile
import time

from sim.finger import (
    NO_EFFECTS,
    ContactObject,
    MotorCommand,
    default_finger_params,
    finger_step,
    initial_finger_state,
)
from sim.hand import HandMotorCommand, default_hand_params, hand_step, initial_hand_state
from sim.params import JOINT_RATIO


def _finger_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of one finger under a 1 kHz controller."""
    p = default_finger_params()
    obj = ContactObject(kind="cylinder")
    st = initial_finger_state(p)
    dt = 1e-3
    steps = int(sim_time_s / dt)
    w = 2.0 * math.pi * 0.5
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        sp = 0.7 - 0.7 * math.cos(w * k * dt)
        # proportional correction on the measured proximal angle (the controller's work)
        goal = JOINT_RATIO * (sp + 0.2 * (sp - st.prox_rad))
        st = finger_step(st, MotorCommand("position", goal), p, obj, NO_EFFECTS, dt)
    return time.perf_counter() - w0, time.process_time() - c0


def _hand_run(sim_time_s: float) -> tuple[float, float]:
    """(wall, CPU) seconds for ``sim_time_s`` of the whole hand under a 1 kHz controller."""
    hp = default_hand_params()
    obj = ContactObject(kind="cylinder")
    st = initial_hand_state(hp)
    dt = 1e-3
    steps = int(sim_time_s / dt)
    w = 2.0 * math.pi * 0.5
    w0, c0 = time.perf_counter(), time.process_time()
    for k in range(steps):
        sp = 0.7 - 0.7 * math.cos(w * k * dt)
        m = MotorCommand("position", JOINT_RATIO * sp)
        cmd = HandMotorCommand((m, m, m), 0.3)
        st = hand_step(st, cmd, hp, obj, NO_EFFECTS, dt)
    return time.perf_counter() - w0, time.process_time() - c0


_C_SRC = r"""
#include <math.h>
#include <stdio.h>
#include <time.h>
/* Same per-step arithmetic as sim.finger._step (4 flexure segments, two pad contacts, the
   implicit tendon solve, stops); a faithful operation count, not a second model. */
int main(int argc, char **argv) {
  long steps = 2000000; double dt = 1e-3;
  double phi = 0, vphi = 0, th = 0, vm = 0, s[4] = {0}, vs[4] = {0};
  double kb = 0.0624, pre = 1.957, kseg = 1.2, rb = 0.01735, rm = 0.01222, kt = 2e4;
  struct timespec a, b; clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
  for (long k = 0; k < steps; ++k) {
    double sp = 0.7 - 0.7 * cos(3.14159 * k * dt);
    double u = 1000.0 * (1.42 * sp - th); if (u > 1023) u = 1023; if (u < -1023) u = -1023;
    double damp = 668.0 * pow(fabs(u) / 50.0 + 1e-9, -0.3) / 5.0 * rm;
    double fr = tanh(vm / 0.005);
    double cm = damp + (1 - fr * fr) / 0.005 * rm, fm = u / 5.0 * rm - fr * rm;
    double jx[4], jy[4], x = 0.06, y = 0, ang = 0, ca = 1, sa = 0;
    for (int i = 0; i < 4; ++i) { jx[i] = x; jy[i] = y; ang += s[i]; ca = cos(ang);
      sa = sin(ang); x += 0.004 * ca; y += 0.004 * sa; }
    double x2 = x + ca * 0.006 - sa * 0.008, y2 = y + sa * 0.006 + ca * 0.008;
    double dx = x2 - 0.052, dy = y2 - 0.008, l12 = sqrt(dx * dx + dy * dy);
    double ux = dx / l12, uy = dy / l12;
    double fphi = -kb * (phi + pre), kphi = kb, cphi = 1e-3, ffl[4], kfl[4], cfl[4];
    for (int i = 0; i < 4; ++i) { ffl[i] = -kseg * s[i]; kfl[i] = kseg; cfl[i] = 3e-3; }
    double cp = cos(phi), spn = sin(phi);
    for (int c = 0; c < 2; ++c) {  /* two pad-cylinder contacts */
      double cx = cp * 0.045 + spn * 0.03, cy = -spn * 0.045 + cp * 0.03;
      double ax = c ? x : 0.01, ay = 0.007, bx = ax + 0.045 * ca, by = ay + 0.045 * sa;
      double ex = bx - ax, ey = by - ay;
      double t = ((cx - ax) * ex + (cy - ay) * ey) / (ex * ex + ey * ey);
      t = t < 0 ? 0 : (t > 1 ? 1 : t);
      double px = ax + t * ex, py = ay + t * ey, ddx = px - cx, ddy = py - cy;
      double dist = sqrt(ddx * ddx + ddy * ddy), depth = 0.02 - dist;
      if (depth > 0) { double nx = ddx / dist, ny = ddy / dist, jn = -py * nx + px * ny;
        fphi += 2000 * depth * jn; kphi += 2000 * jn * jn; cphi += 5 * jn * jn;
        if (c) for (int i = 0; i < 4; ++i) { double ji = -(py - jy[i]) * nx + (px - jx[i]) * ny;
          ffl[i] += 2000 * depth * ji; kfl[i] += 2000 * ji * ji; cfl[i] += 5 * ji * ji; } }
    }
    double dphi = 1.9e-4 + dt * cphi + dt * dt * kphi, aphi = (1.9e-4 * vphi + dt * fphi) / dphi;
    double dm = 3e-3 + dt * cm, am = (3e-3 * vm + dt * fm) / dm;
    double A = -rb * aphi + rm * am, B = dt * (rb * rb / dphi + rm * rm / dm), g[4], bb[4], aa[4];
    for (int i = 0; i < 4; ++i) { g[i] = ux * (y2 - jy[i]) - uy * (x2 - jx[i]);
      double di = 2e-5 + dt * cfl[i] + dt * dt * kfl[i]; aa[i] = (2e-5 * vs[i] + dt * ffl[i]) / di;
      bb[i] = dt * g[i] / di; A -= g[i] * aa[i]; B += g[i] * bb[i]; }
    double e = rm * th + (l12 - 0.030) - rb * phi - 5e-4, kk = kt * dt + 20;
    double F = (kt * e + kk * A) / (1 + kk * B); if (F < 0) F = 0;
    vphi = aphi + dt * rb * F / dphi; vm = am - dt * rm * F / dm;
    phi += dt * vphi; if (phi < 0) { phi = 0; if (vphi < 0) vphi = 0; }
    if (phi > 2.8) { phi = 2.8; if (vphi > 0) vphi = 0; }
    for (int i = 0; i < 4; ++i) { vs[i] = aa[i] + bb[i] * F; s[i] += dt * vs[i];
      if (s[i] < -0.05) { s[i] = -0.05; if (vs[i] < 0) vs[i] = 0; }
      if (s[i] > 0.45) { s[i] = 0.45; if (vs[i] > 0) vs[i] = 0; } }
    th += dt * vm;
  }
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
  double wall = (b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec);
  printf("%.6f %.6f\n", wall / steps * 1e9, phi);
  return 0;
}
"""


def _c_step_s() -> float | None:
    """Wall seconds per step of the equivalent C loop (gcc -O2), or None without gcc."""
    gcc = shutil.which("gcc")
    if gcc is None:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        src = os.path.join(tmp, "step.c")
        exe = os.path.join(tmp, "step")
        with open(src, "w", encoding="utf-8") as fh:
            fh.write(_C_SRC)
        try:
            subprocess.run([gcc, "-O2", "-o", exe, src, "-lm"], check=True,
                           capture_output=True, timeout=60)
            out = subprocess.run([exe], check=True, capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.SubprocessError):
            return None
        return float(out.stdout.split()[0]) * 1e-9


def bench_sim(sim_time_s: float = 10.0, repeats: int = 3) -> dict[str, float]:
    """Figures for ``teleop bench sim``: real-time factors (best of ``repeats``).

    ``*_realtime_factor`` use the process's CPU time (robust to other load on the machine);
    ``*_wall`` the wall clock.
    """
    finger = [_finger_run(sim_time_s) for _ in range(repeats)]
    hand = [_hand_run(sim_time_s / 2.0) for _ in range(repeats)]
    f_cpu = min(c for _, c in finger)
    f_wall = min(w for w, _ in finger)
    h_cpu = min(c for _, c in hand)
    h_wall = min(w for w, _ in hand)
    out: dict[str, float] = {
        "sim_time_s": sim_time_s,
        "controller_rate_hz": 1000.0,
        "physics_dt_s": 1e-3,
        "finger_realtime_factor": sim_time_s / f_cpu,
        "finger_realtime_factor_wall": sim_time_s / f_wall,
        "finger_step_us": f_cpu / (sim_time_s * 1000.0) * 1e6,
        "hand_realtime_factor": (sim_time_s / 2.0) / h_cpu,
        "hand_realtime_factor_wall": (sim_time_s / 2.0) / h_wall,
        "hand_step_us": h_cpu / (sim_time_s / 2.0 * 1000.0) * 1e6,
    }
    out["realtime_factor"] = out["finger_realtime_factor"]
    c_step = _c_step_s()
    if c_step is not None:
        out["c_equivalent_step_us"] = c_step * 1e6
        out["c_equivalent_realtime_factor"] = 1e-3 / c_step
        out["python_over_c_slowdown"] = out["finger_step_us"] / (c_step * 1e6)
    return out
