#!/usr/bin/env python3
"""CFD validation of scalemesh beyond the straight tube (issue 31, item 2):
a curved tube (Dean flow) and the stenosis phantom, each at several M, against
a reference by Richardson extrapolation from the three finest meshes.

Curved tube: an open-ended STL this script writes, a 90-degree torus segment
(tube radius a = 1.5 mm, bend radius R = 6 mm, a/R = 0.25) between straight
inlet and outlet legs of 4 diameters; scalemesh caps the open ends and names
them by `[[openings]] near = ...`. Laminar, Re = U D / nu = 120, Dean number
De = Re sqrt(a/R) = 60. Measured: the pressure drop between cross-sections in
the two legs, 2 diameters before and after the bend, and the mean wall shear
stress on the bend's outer and inner walls and their ratio.

Stenosis: the phantom of cases/stenosis (6 mm tube narrowing to 3 mm at
z = 0), laminar Re = 20 at the inlet (40 in the throat). Measured: the
pressure drop across the throat (slabs at z = -8 and +8 mm) and the mean and
peak wall shear stress in the throat (|z| < 1 mm).

    python3 validation/curved_validation.py --scalemesh build/src/cli/scalemesh
        # writes validation/curved_results.json, validation/curved.png
        # (gnuplot) and the curved/stenosis section of docs/validation.md
    python3 validation/curved_validation.py --from-json validation/curved_results.json
        # rewrites the section only

Needs python3 (stdlib only), OpenFOAM v1912 (simpleFoam, postProcess,
checkMesh); gnuplot for the plot. Shares its OpenFOAM helpers with
tube_validation.py through validation/common.py. Not part of ctest.
"""

import argparse
import concurrent.futures
import json
import math
import os
import shutil
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree (ctest runs this from it)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (REPO, have_gnuplot, write_series, run_gnuplot,  # noqa: E402
                    cpu_model, log, run, solve, latest_time, internal_field, patch_field,  # noqa: E402
                    boundary_faces, replace_section, CURVED_BEGIN, CURVED_END)

U_IN = 0.1            # m/s, uniform inflow

# Curved tube (mm)
BEND_A = 1.5          # tube radius
BEND_R = 6.0          # bend radius (centreline)
LEG = 12.0            # straight legs, 4 diameters
AROUND = 48           # STL segments around
BEND_RE = 120.0       # U D / nu
BEND_NU = U_IN * 2 * BEND_A * 1e-3 / BEND_RE
BEND_DEAN = BEND_RE * math.sqrt(BEND_A / BEND_R)
BEND_SLAB = 6.0       # pressure cross-sections 6 mm (2 D) before and after the bend
SLAB_HALF = 0.5       # half-thickness of the pressure slabs, mm
SECTOR_DEG = 45.0     # outer / inner wall: within 45 degrees of the bend plane
BEND_THETA = (30.0, 90.0)   # part of the bend measured, degrees from its start

# Stenosis (mm)
STEN_RE = 20.0        # at the 6 mm inlet
STEN_NU = U_IN * 6e-3 / STEN_RE
STEN_SLAB = 8.0       # pressure slabs at z = -8 and +8 mm
THROAT_HALF = 1.0     # throat: |z| < 1 mm

DEFAULT_M = [5, 7, 10, 14, 20, 28]

QUANTITIES = {
    "bend": [("dp", "pressure drop, legs 2 D before / after the bend (m^2/s^2)"),
             ("wss_outer", "mean WSS, outer wall of the bend (m^2/s^2)"),
             ("wss_inner", "mean WSS, inner wall of the bend (m^2/s^2)"),
             ("wss_ratio", "WSS outer / inner")],
    "stenosis": [("dp", "pressure drop across the throat, z = -8 to +8 mm (m^2/s^2)"),
                 ("wss_mean", "mean WSS in the throat, -1 < z < 1 mm (m^2/s^2)"),
                 ("wss_peak", "peak face WSS in the throat (m^2/s^2)")],
}


# ---------------------------------------------------------------- geometry

def bend_centre(s):
    """Centreline point and the unit vector pointing away from the bend's
    centre of curvature (the outer side), at arc length s (mm) from the start
    of the inlet leg. The inlet leg runs along +z from z = -LEG to 0, the bend
    turns in the x-z plane about (R, 0, 0), the outlet leg runs along +x at
    z = R."""
    R = BEND_R
    if s <= LEG:
        return (0.0, 0.0, s - LEG), (-1.0, 0.0, 0.0)
    arc = 0.5 * math.pi * R
    if s <= LEG + arc:
        th = (s - LEG) / R
        return (R - R * math.cos(th), 0.0, R * math.sin(th)), (-math.cos(th), 0.0, math.sin(th))
    return (R + (s - LEG - arc), 0.0, R), (0.0, 0.0, 1.0)


def write_bend_stl(path):
    """The open-ended curved tube as an ASCII STL (triangles facing out)."""
    total = 2 * LEG + 0.5 * math.pi * BEND_R
    step = 2 * math.pi * BEND_A / AROUND           # about square quads
    rings = []
    n_along = int(math.ceil(total / step))
    for i in range(n_along + 1):
        c, n = bend_centre(total * i / n_along)
        b = (0.0, 1.0, 0.0)
        ring = []
        for k in range(AROUND):
            psi = 2 * math.pi * k / AROUND
            ring.append(tuple(c[j] + BEND_A * (math.cos(psi) * n[j] + math.sin(psi) * b[j]) for j in range(3)))
        rings.append(ring)

    def facet(p, q, r):
        u = [q[j] - p[j] for j in range(3)]
        v = [r[j] - p[j] for j in range(3)]
        nn = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
        ln = math.sqrt(sum(x * x for x in nn)) or 1.0
        return ("facet normal %.6e %.6e %.6e\n outer loop\n  vertex %.9e %.9e %.9e\n  vertex %.9e %.9e %.9e\n"
                "  vertex %.9e %.9e %.9e\n endloop\nendfacet\n" % ((nn[0] / ln, nn[1] / ln, nn[2] / ln) + p + q + r))

    out = ["solid bend\n"]
    for i in range(n_along):
        a, b = rings[i], rings[i + 1]
        for k in range(AROUND):
            k1 = (k + 1) % AROUND
            # (n, b, t) is left-handed (n x b = -t, t along the flow): psi
            # turns clockwise about t, so these have their normals out.
            out.append(facet(a[k], b[k1], a[k1]))
            out.append(facet(a[k], b[k], b[k1]))
    out.append("endsolid bend\n")
    with open(path, "w") as f:
        f.writelines(out)
    return 2 * n_along * AROUND


# ---------------------------------------------------------------- meshes

def case_toml(kind, M):
    if kind == "bend":
        end_in = bend_centre(0.0)[0]
        end_out = bend_centre(2 * LEG + 0.5 * math.pi * BEND_R)[0]
        return """# Curved tube (torus segment, a = %g mm, R = %g mm) with straight legs,
# an open-ended STL written by validation/curved_validation.py.
[input]
file = "bend.stl"
units = "mm"

[sizing]
M = %g
L_min = "0.05 mm"
L_max = "20 mm"

[output]
surface = []

[[openings]]
name = "inlet"
type = "inlet"
near = [%g, %g, %g]

[[openings]]
name = "outlet"
type = "outlet"
near = [%g, %g, %g]

[flow]
viscosity = %g
inlet_speed = %g
""" % ((BEND_A, BEND_R, M) + end_in + end_out + (BEND_NU, U_IN))
    toml = open(os.path.join(REPO, "cases", "stenosis", "scalemesh.toml")).read()
    toml = toml.replace("[sizing]\n", "[sizing]\nM = %g\n" % M, 1)
    toml += "\n[output]\nsurface = []\n\n[flow]\nviscosity = %g\ninlet_speed = %g\n" % (STEN_NU, U_IN)
    return toml


def scalemesh_case(binary, kind, M, case):
    if os.path.exists(case):
        shutil.rmtree(case)
    os.makedirs(case)
    if kind == "bend":
        write_bend_stl(os.path.join(case, "bend.stl"))
    with open(os.path.join(case, "scalemesh.toml"), "w") as f:
        f.write(case_toml(kind, M))
    t = time.time()
    run([binary, "run", case, "-q"], case, "log.scalemesh")
    return time.time() - t


# ---------------------------------------------------------------- analysis

def norm(v):
    return math.sqrt(sum(x * x for x in v))


def fields(case):
    d = latest_time(case)
    return (internal_field(os.path.join(d, "p"), 1), internal_field(os.path.join(d, "C"), 3),
            internal_field(os.path.join(d, "V"), 1), d)


def slab_mean(p, C, V, inside):
    pv = v = 0.0
    for pi, ci, vi in zip(p, C, V):
        if inside(ci):
            pv += pi * vi
            v += vi
    if v == 0:
        raise RuntimeError("empty slab")
    return pv / v


def wall_wss(case, time_dir):
    patches, _, _ = boundary_faces(case)
    wss = patch_field(os.path.join(time_dir, "wallShearStress"), "wall", 3)
    wall = patches["wall"]
    if len(wss) != len(wall):
        raise RuntimeError("wallShearStress has %d wall values, the wall %d faces" % (len(wss), len(wall)))
    return [(tuple(x * 1e3 for x in c), norm(a), norm(t)) for (c, a), t in zip(wall, wss)], patches


def analyse_bend(case):
    p, C, V, d = fields(case)
    h = SLAB_HALF * 1e-3
    zin = -BEND_SLAB * 1e-3
    xout = (BEND_R + BEND_SLAB) * 1e-3
    dp = (slab_mean(p, C, V, lambda c: abs(c[2] - zin) < h)
          - slab_mean(p, C, V, lambda c: abs(c[0] - xout) < h and c[2] > 0))
    faces, patches = wall_wss(case, d)
    cos_sector = math.cos(math.radians(SECTOR_DEG))
    sums = {"outer": [0.0, 0.0], "inner": [0.0, 0.0]}
    for c, area, tau in faces:
        th = math.degrees(math.atan2(c[2], BEND_R - c[0]))
        if not (BEND_THETA[0] <= th <= BEND_THETA[1]) or c[2] < -1e-9:
            continue
        t = math.radians(th)
        q = (BEND_R - BEND_R * math.cos(t), 0.0, BEND_R * math.sin(t))
        e = (-math.cos(t), 0.0, math.sin(t))
        r = [c[j] - q[j] for j in range(3)]
        cosphi = sum(r[j] * e[j] for j in range(3)) / max(norm(r), 1e-12)
        side = "outer" if cosphi > cos_sector else "inner" if cosphi < -cos_sector else None
        if side:
            sums[side][0] += tau * area
            sums[side][1] += area
    outer = sums["outer"][0] / sums["outer"][1]
    inner = sums["inner"][0] / sums["inner"][1]
    inlet_area = sum(norm(a) for c, a in patches["inlet"])
    return {"cells": len(p), "dp": dp, "wss_outer": outer, "wss_inner": inner, "wss_ratio": outer / inner,
            "inlet_area_mm2": inlet_area * 1e6,
            # straight-tube references for scale: Poiseuille at the same flow rate
            "wss_poiseuille": 4 * BEND_NU * (U_IN * inlet_area / (math.pi * (BEND_A * 1e-3) ** 2)) / (BEND_A * 1e-3)}


def analyse_stenosis(case):
    p, C, V, d = fields(case)
    h = SLAB_HALF * 1e-3
    z = STEN_SLAB * 1e-3
    dp = slab_mean(p, C, V, lambda c: abs(c[2] + z) < h) - slab_mean(p, C, V, lambda c: abs(c[2] - z) < h)
    faces, patches = wall_wss(case, d)
    st = sa = peak = 0.0
    for c, area, tau in faces:
        if abs(c[2]) < THROAT_HALF:
            st += tau * area
            sa += area
            peak = max(peak, tau)
    return {"cells": len(p), "dp": dp, "wss_mean": st / sa, "wss_peak": peak,
            "inlet_area_mm2": sum(norm(a) for c, a in patches["inlet"]) * 1e6}


def study_one(kind, M, case, binary, reuse=False):
    saved = os.path.join(case, "curved_result.json")
    if reuse and os.path.exists(saved):
        result = json.load(open(saved))
        result["reused"] = True
        log("%-8s M %-3g reused from %s" % (kind, M, saved))
        return result
    try:
        mesh_seconds = scalemesh_case(binary, kind, M, case)
        result = {"case": kind, "M": M, "mesh_seconds": mesh_seconds}
        result.update(solve(case))
        result.update(analyse_bend(case) if kind == "bend" else analyse_stenosis(case))
    except Exception as e:  # one failed mesh does not stop the study
        log("%s M = %g FAILED: %s" % (kind, M, str(e)[:2000]))
        return {"case": kind, "M": M, "failed": str(e)[:500]}
    with open(saved, "w") as f:
        json.dump(result, f, indent=1)
    log("%-8s M %-3g cells %7d  %s  %s, %d iterations, mesh %.0f s, solver %.0f s" % (
        kind, M, result["cells"], "  ".join("%s %.5g" % (k, result[k]) for k, _ in QUANTITIES[kind]),
        "converged" if result["converged"] else "NOT converged", result["iterations"], mesh_seconds,
        result["solver_seconds"]))
    return result


# ---------------------------------------------------------------- Richardson

def richardson(rows, key):
    """Richardson extrapolation from the three finest meshes of `rows` (each
    with "cells" and `key`), after Celik et al. (2008, J. Fluids Eng. 130,
    078001) for non-constant refinement ratios: representative size
    h = (1 / cells)^(1/3), observed order p by fixed-point iteration, GCI of
    the finest mesh per Roache with safety factor 1.25. Falls back to the
    finest-mesh value (no GCI) when p is not in (0.5, 4), the three do not
    determine it, or the change between the two finest is not shrinking."""
    rs = sorted((r for r in rows if "failed" not in r), key=lambda r: -r["cells"])
    out = {"key": key, "meshes": [r["M"] for r in rs[:3]]}
    if len(rs) < 3:
        out.update(value=rs[0][key] if rs else None, order=None, gci=None,
                   note="fewer than three meshes: finest-mesh value")
        return out
    f1, f2, f3 = (r[key] for r in rs[:3])
    r21 = (rs[0]["cells"] / rs[1]["cells"]) ** (1 / 3)
    r32 = (rs[1]["cells"] / rs[2]["cells"]) ** (1 / 3)
    e21, e32 = f2 - f1, f3 - f2
    out.update(r21=r21, r32=r32)
    if e21 == 0 or e32 == 0:
        out.update(value=f1, order=None, gci=None, note="two meshes agree exactly: finest-mesh value")
        return out
    s = 1.0 if e32 / e21 > 0 else -1.0
    if abs(e21) >= abs(e32) * math.log(r21) / math.log(r32):
        # e21 / e32 = (r21^p - 1) / (r21^p (r32^p - 1)) tends to
        # ln r21 / ln r32 as p -> 0: at or above it the change is not
        # shrinking (p <= 0), whatever order the absolute value would give
        out.update(value=f1, order=None, gci=None, oscillatory=s < 0,
                   note="change not shrinking with refinement (f1 - f2 = %.3g, f2 - f3 = %.3g)%s: "
                        "finest-mesh value" % (-e21, -e32, ", oscillatory" if s < 0 else ""))
        return out
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    ok = True
    for _ in range(200):
        try:
            q = math.log((r21 ** p - s) / (r32 ** p - s))
        except (ValueError, ZeroDivisionError):
            ok = False
            break
        p_new = abs(math.log(abs(e32 / e21)) + q) / math.log(r21)
        if abs(p_new - p) < 1e-10:
            p = p_new
            break
        p = p_new
    out["order"] = p if ok else None
    out["oscillatory"] = s < 0
    if not ok or not (0.5 < p < 4):
        out.update(value=f1, gci=None,
                   note="observed order %s outside (0.5, 4)%s: finest-mesh value" % (
                       ("%.2f" % p) if ok else "undetermined", ", oscillatory convergence" if s < 0 else ""))
        return out
    ext = (r21 ** p * f1 - f2) / (r21 ** p - 1)
    gci = 1.25 * abs((f1 - f2) / f1) / (r21 ** p - 1)
    out.update(value=ext, gci=gci, note="Richardson%s" % (" (oscillatory convergence)" if s < 0 else ""))
    return out


def reference(results):
    ref = {}
    for kind, qs in QUANTITIES.items():
        rows = [r for r in results if r["case"] == kind]
        ref[kind] = {k: richardson(rows, k) for k, _ in qs}
        for r in rows:
            if "failed" in r:
                continue
            for k, _ in qs:
                v = ref[kind][k]["value"]
                r[k + "_error"] = (r[k] / v - 1) if v else None
    return ref


# ---------------------------------------------------------------- report

def plot(results, png, workdir):
    if not have_gnuplot():
        return False
    panels = []
    for kind, title in (("bend", "Curved tube, De = %.0f" % BEND_DEAN), ("stenosis", "Stenosis, Re = %.0f" % STEN_RE)):
        rows = sorted((r for r in results if r["case"] == kind and "failed" not in r), key=lambda r: r["cells"])
        # a zero error (the finest mesh against a finest-mesh fallback) is left out
        path = write_series(os.path.join(workdir, "plot-%s.dat" % kind), (
            [r["cells"]] + [abs(r[k + "_error"]) * 100 if r.get(k + "_error") else None for k, _ in QUANTITIES[kind]]
            for r in rows))
        curves = ", ".join("'%s' u 1:%d w lp pt %d lw 2 t '%s'" % (path, i + 2, 5 + 2 * i, k)
                           for i, (k, _) in enumerate(QUANTITIES[kind]))
        panels.append('set title "%s: |error| against the reference"\nplot %s, 1 w l dt 2 lc "black" t "1%%"'
                      % (title, curves))
    script = """set terminal pngcairo size 1200,500 font ",11"
set output '%s'
set multiplot layout 1,2
set logscale xy
set grid
set xlabel "cells"
set ylabel "|error| (%%)"
set key bottom left noenhanced
set datafile missing "NaN"
%s
unset multiplot
""" % (png, "\n".join(panels))
    return run_gnuplot(script, os.path.join(workdir, "curved-plot.gp"))


def fmt(v):
    return "%.5g" % v if v is not None else "-"


def within(rows, key, tol, fallback):
    """The smallest M from which every mesh's |error| is within tol, as
    'M = m (cells)', or 'none'. With a fallback reference (the finest mesh's
    value) the finest mesh is left out: its error is zero by definition."""
    rs = sorted((r for r in rows if "failed" not in r and r.get(key + "_error") is not None), key=lambda r: r["cells"])
    if fallback:
        rs = rs[:-1]
    best = None
    for r in reversed(rs):
        if abs(r[key + "_error"]) > tol:
            break
        best = r
    return "M = %g, %d cells" % (best["M"], best["cells"]) if best else "none"


def tables(results, ref):
    out = []
    for kind, qs in QUANTITIES.items():
        rows = sorted((r for r in results if r["case"] == kind), key=lambda r: r["M"])
        head = "| M | cells | " + " | ".join("%s (error)" % k for k, _ in qs) + " | iterations |"
        out += [head, "|" + "---|" * (len(qs) + 3)]
        for r in rows:
            if "failed" in r:
                out.append("| %g | failed | %s |" % (r["M"], " | ".join("-" for _ in qs) + " | -"))
                continue
            cells = ["%s (%+.2f%%)" % (fmt(r[k]), 100 * r[k + "_error"]) if r.get(k + "_error") is not None
                     else fmt(r[k]) for k, _ in qs]
            out.append("| %g | %d | %s | %d%s |" % (r["M"], r["cells"], " | ".join(cells), r["iterations"],
                                                   "" if r["converged"] else " (not converged)"))
        out.append("| reference | | %s | |" % " | ".join(fmt(ref[kind][k]["value"]) for k, _ in qs))
        out += ["", "Coarsest mesh whose error against the reference is within 1% (5%), it and every finer "
                "mesh: " + "; ".join("%s %s (%s)" % (k, within(rows, k, 0.01, ref[kind][k].get("gci") is None),
                                   within(rows, k, 0.05, ref[kind][k].get("gci") is None)) for k, _ in qs)
                + ". (Where the reference is the finest-mesh fallback, the finest mesh is left out.)"]
        out += ["", "| quantity | meshes (M) | observed order p | GCI (finest) | reference |", "|---|---|---|---|---|"]
        for k, name in qs:
            a = ref[kind][k]
            out.append("| %s | %s | %s | %s | %s |" % (
                name, ", ".join("%g" % m for m in a["meshes"]), ("%.2f" % a["order"]) if a.get("order") else "-",
                ("%.2f%%" % (100 * a["gci"])) if a.get("gci") is not None else "-", a["note"]))
        out.append("")
    return out


def write_section(results, ref, doc, png, meta):
    ok = [r for r in results if "failed" not in r]
    rel_png = os.path.relpath(png, os.path.dirname(doc))
    t = tables(results, ref)
    # split the two cases' tables
    split = next(i for i, line in enumerate(t) if i > 0 and line.startswith("| M |"))
    bend_tab, sten_tab = "\n".join(t[:split]).strip(), "\n".join(t[split:]).strip()
    text = """{begin}

# CFD validation: curved tube and stenosis (Richardson extrapolation)

Generated by `validation/curved_validation.py` (issue 31, item 2); do not
edit by hand. No analytic solution here: each quantity's reference is the
Richardson extrapolation from the three finest scalemesh meshes (after Celik
et al. 2008 for unequal refinement ratios: representative size
h = cells^(-1/3), observed order p, GCI of the finest mesh with safety factor
1.25 per Roache); where p is not in (0.5, 4), or the change between the two
finest meshes is not smaller than the one before (no sign of convergence), the
reference falls back to the finest-mesh value, as the last column says. Errors are of each mesh against
that reference, so the finest mesh's error is only as meaningful as the
reference (and is zero where the fallback applies). Caveat: scalemesh meshes
at different M are not a systematic refinement of one mesh (each M remeshes
the wall and places its own layers), so the observed orders are those of the
whole meshing and solving chain, not of the discretisation alone.

OpenFOAM set-up as in the straight tube: the `system/`, `constant/` and `0/`
scalemesh writes (simpleFoam, laminar, uniform inflow {u:g} m/s normal to the
inlet, p = 0 at the outlet, no-slip wall), run until SIMPLE's residual
control stops it; wall shear stress by `wallShearStress`, kinematic values
(m^2/s^2); pressures are volume-weighted means over 1 mm slabs.

## Curved tube (Dean flow)

An open-ended STL ({around} segments around, written by the script): a
90-degree torus segment of tube radius a = {a:g} mm and bend radius
R = {R:g} mm (a/R = {ratio:g}) between straight legs of {leg:g} mm (4
diameters); scalemesh caps the two open ends and names them by
`[[openings]] near = ...` (`L_min = "0.05 mm"`, `L_max = "20 mm"`).
nu = {bnu:.3g} m^2/s: Re = U D / nu = {bre:g}, Dean number
De = Re sqrt(a/R) = {de:g}. The legs are shorter than the entrance length at
this Re (about 0.06 Re D = {entr:.0f} mm), so the flow entering the bend is
still developing; that is part of the problem solved, the same on every mesh.
Pressure drop: the inlet-leg slab at z = -{slab:g} mm minus the outlet-leg
slab at x = R + {slab:g} mm (each 2 diameters from the bend). Outer and inner
wall: wall faces within {sector:g} degrees of the bend plane on the side away
from (outer) or towards (inner) the centre of curvature, in the part of the
bend from {th0:g} to {th1:g} degrees. For scale, Poiseuille's wall shear stress
in a straight tube of radius a at mean speed U = {u:g} m/s, 4 nu U / a, is
{wp:.4g} m^2/s^2.

{bend}

## Stenosis

The phantom of `cases/stenosis` (6 mm tube narrowing smoothly to 3 mm at
z = 0 over |z| < 5 mm, voxelised at 0.5 mm, clipped at z = -12 and +12 mm)
with that case file's settings and M set. nu = {snu:.3g} m^2/s: Re = {sre:g} at
the 6 mm inlet, {sre2:g} in the throat. Pressure drop: slabs at z = -{sslab:g}
and +{sslab:g} mm. Throat: wall faces with |z| < {th:g} mm, their
area-weighted mean |wallShearStress| and the largest face value (a single
face's value: noisier than the mean, and Richardson on a maximum is
doubtful). The voxel-derived wall is remeshed at each M, so the geometry
itself changes slightly between meshes.

{sten}

![error against cell count]({png})

## Rerun

```sh
bash setup.sh validate      # the straight tube first, then this
# or, with the binary already built:
nice -n 19 /usr/bin/python3 validation/curved_validation.py --scalemesh build/src/cli/scalemesh \\
    --workdir /tmp/scalemesh-curved --M {Ms} --jobs {jobs}
```

This run: {nmesh} meshes on {machine}, {jobs} case(s) at a time, {context}; meshing {mesh_min:.1f}
minutes and simpleFoam {solver_min:.1f} minutes in all (summed over the
meshes), {wall_min:.1f} minutes wall clock including post-processing
({date}{reused}). It writes
`validation/curved_results.json`, `validation/curved.png` and this section.

{end}""".format(
        begin=CURVED_BEGIN, end=CURVED_END, u=U_IN, around=AROUND, a=BEND_A, R=BEND_R, ratio=BEND_A / BEND_R,
        leg=LEG, bnu=BEND_NU, bre=BEND_RE, de=BEND_DEAN, entr=0.06 * BEND_RE * 2 * BEND_A, slab=BEND_SLAB,
        sector=SECTOR_DEG, th0=BEND_THETA[0], th1=BEND_THETA[1],
        wp=4 * BEND_NU * U_IN / (BEND_A * 1e-3),
        bend=bend_tab, snu=STEN_NU, sre=STEN_RE, sre2=2 * STEN_RE, sslab=STEN_SLAB, th=THROAT_HALF, sten=sten_tab,
        png=rel_png, Ms=" ".join("%g" % m for m in meta["M"]), nmesh=len(ok), machine=meta["machine"],
        context=meta.get("context") or "under `nice -n 19` next to a CI build using the same cores",
        jobs=meta["jobs"], mesh_min=sum(r["mesh_seconds"] for r in ok) / 60,
        solver_min=sum(r["solver_seconds"] for r in ok) / 60, wall_min=meta["wall_seconds"] / 60, date=meta["date"],
        reused=("; %d of the meshes' results reused (`--reuse`) from an earlier invocation in the same work "
                "directory, whose %s are in the meshing and simpleFoam sums but not in this wall clock" % (
                    meta["reused"], ("%.1f minutes wall clock" % (meta["earlier_wall_seconds"] / 60))
                    if meta.get("earlier_wall_seconds") else "times"))
        if meta.get("reused") else "")
    replace_section(doc, text)


def machine():
    return "%s, %d cores" % (cpu_model(), os.cpu_count() or 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scalemesh", default=os.path.join(REPO, "build", "src", "cli", "scalemesh"))
    ap.add_argument("--workdir", default="/tmp/scalemesh-curved")
    ap.add_argument("--M", type=float, nargs="+", default=DEFAULT_M)
    ap.add_argument("--cases", nargs="+", default=["bend", "stenosis"], choices=["bend", "stenosis"])
    ap.add_argument("--jobs", type=int, default=1, help="cases run at a time")
    ap.add_argument("--reuse", action="store_true",
                    help="take a mesh's result from an earlier run in the same --workdir when there is one")
    ap.add_argument("--context", help="what else ran on the machine during the run, for the page (default: "
                    "a CI build under nice -n 19, as `bash setup.sh validate` is usually run)")
    ap.add_argument("--from-json", help="rewrite the section from a curved_results.json, running nothing")
    ap.add_argument("--out", default=os.path.join(REPO, "validation"), help="curved_results.json, curved.png")
    ap.add_argument("--doc", default=os.path.join(REPO, "docs", "validation.md"))
    args = ap.parse_args()
    png = os.path.join(args.out, "curved.png")
    os.makedirs(args.workdir, exist_ok=True)
    if args.from_json:
        data = json.load(open(args.from_json))
        results, meta = data["results"], data["meta"]
        if args.context:
            meta["context"] = args.context
        ref = reference(results)
        data["reference"] = ref
        with open(os.path.join(args.out, "curved_results.json"), "w") as f:
            json.dump(data, f, indent=1)
        plot(results, png, args.workdir)
        write_section(results, ref, args.doc, png, meta)
        log("wrote %s from %s" % (args.doc, args.from_json))
        return 0
    binary = os.path.abspath(args.scalemesh)
    if not os.access(binary, os.X_OK):
        sys.exit("no scalemesh binary at %s (build it, or pass --scalemesh)" % binary)
    start = time.time()
    jobs = [(kind, M) for M in args.M for kind in args.cases]
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futs = [pool.submit(study_one, kind, M, os.path.join(args.workdir, "%s-M%g" % (kind, M)), binary,
                            args.reuse)
                for kind, M in jobs]
        results = [f.result() for f in futs]
    meta = {"M": args.M, "jobs": args.jobs, "machine": machine(), "wall_seconds": time.time() - start,
            "context": args.context,
            "date": time.strftime("%Y-%m-%d", time.gmtime()), "reused": sum(1 for r in results if r.get("reused"))}
    ref = reference(results)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "curved_results.json"), "w") as f:
        json.dump({"meta": meta, "results": results, "reference": ref}, f, indent=1)
    plot(results, png, args.workdir)
    write_section(results, ref, args.doc, png, meta)
    log("\n".join(tables(results, ref)))
    log("wrote %s, %s/curved_results.json, curved.png" % (args.doc, args.out))
    return 0 if all("failed" not in r for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
