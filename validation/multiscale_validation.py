#!/usr/bin/python3
"""Multi-scale flow benchmark, first step: a stepped tube in series.

One tube along z made of straight segments of diameters 8, 4, 2 and 1 mm,
each 8 diameters long, joined by conical tapers (each 2 larger diameters
long), is built exactly with Gmsh's OpenCASCADE kernel and its surface
written as an STL (about 24 triangles around each circumference). scalemesh
meshes it at several M (inlet clip plane in the 8 mm segment, outlet in the
1 mm one), OpenFOAM's simpleFoam solves laminar flow on each mesh with the
settings scalemesh writes, and each segment's developed middle (the middle
half of its straight length) is compared with Hagen-Poiseuille: a tube whose
feature size spans a factor of 8 should be resolved equally well in every
segment at one M.

    /usr/bin/python3 validation/multiscale_validation.py            # M = 5 7 10
    /usr/bin/python3 validation/multiscale_validation.py --quick    # M = 5 only,
        # at most 500 SIMPLE iterations: a smoke test
    /usr/bin/python3 validation/multiscale_validation.py --M 7 --gmsh-h 0.8 0.5
        # also Gmsh peers: isotropic tets of 0.8 and 0.5 mm (40k, 160k cells)
        # on the same geometry

It prints a Markdown table, one row per mesh and segment, and writes the
results to --out (JSON). Runs go into --workdir (one case directory per mesh,
the STL in its root).

Needs: /usr/bin/python3 with the Gmsh Python module (Debian python3-gmsh),
OpenFOAM v1912 (simpleFoam, postProcess, checkMesh; gmshToFoam and
transformPoints for the Gmsh peer) and a scalemesh binary.

Flow and reference values (kinematic, as OpenFOAM's incompressible solvers
report them): nu = 1e-3 m^2/s as validation/tube_validation.py, a uniform
inlet speed U_IN over the 8 mm inlet cap; the flow rate Q = U_IN x the
mesh's inlet patch area. The Reynolds number 4 Q / (pi nu D) is largest in
the 1 mm segment, about 3, so the entrance length (about 0.06 Re D, plus a
diameter of creeping-flow adjustment) is short against each segment's
straight length. For a segment of radius R:
    wall shear stress   tau_w / rho  = 4 nu Q / (pi R^3)
    pressure gradient  -dp/dz / rho  = 8 nu Q / (pi R^4)
Measured per segment: the area-weighted mean |wallShearStress| of the wall
faces whose centres lie in the middle half, its local RMS deviation from
tau_w, the slope of the volume-weighted least-squares line through the cell
centres' pressures there, the cells across a diameter (the cells a line
through the axis in the middle cross-section passes through, i.e. the
interior faces it crosses plus one, averaged over 4 directions 45 degrees
apart) and the mesh's cross-section (cell volume / length) against pi R^2.
"""

import argparse
import json
import math
import os
import re
import shutil
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (log, run, solve, latest_time, internal_field,  # noqa: E402
                    patch_field, boundary_faces, foam_list_lines)

NU = 1e-3           # m^2/s, as tube_validation.py
U_IN = 0.05         # m/s over the 8 mm inlet: Q = 2.5e-6 m^3/s, Re = 3.2 in the 1 mm segment
DIAMETERS = [8.0, 4.0, 2.0, 1.0]   # mm, inlet to outlet
SEGMENT_DIAMETERS = 8.0            # straight length of each segment, in its diameters
TAPER_DIAMETERS = 2.0              # length of each cone, in the larger diameter
# The STL runs on past each clip plane (scalemesh cuts there): the inlet cap
# lies INLET_MARGIN mm inside the 8 mm end, the outlet cap OUTLET_MARGIN mm
# inside the 1 mm end, so that the straight lengths between caps and tapers
# are 8 diameters.
INLET_MARGIN = 2.0
OUTLET_MARGIN = 1.0
STL_NAME = "surface.stl"
CURVATURE_ELEMENTS = 24            # surface triangles around a circumference

DEFAULT_M = [5, 7, 10]
QUICK_ITERATIONS = 500
LINE_ANGLES = [0, 45, 90, 135]     # degrees from x of the diameter lines counted in each cross-section
LINE_OFFSET = 0.0123               # their distance from the axis, in radii: off any symmetry of the mesh


# ---------------------------------------------------------------- geometry

def layout():
    """The stepped tube along z, in mm, from the inlet cap at z = 0: a list of
    (diameter, z0, z1) of the straight segments between the caps and tapers,
    the cone (z0, z1, D0, D1) list and the outlet cap's z."""
    segments, cones, z = [], [], 0.0
    for i, d in enumerate(DIAMETERS):
        segments.append((d, z, z + SEGMENT_DIAMETERS * d))
        z += SEGMENT_DIAMETERS * d
        if i + 1 < len(DIAMETERS):
            cones.append((z, z + TAPER_DIAMETERS * d, d, DIAMETERS[i + 1]))
            z += TAPER_DIAMETERS * d
    return segments, cones, z


def build_geometry(gmsh, inlet_margin, outlet_margin):
    """The stepped tube as one OCC volume in the current Gmsh model: cylinders
    and cones fused, flat discs at the ends, `inlet_margin` mm before z = 0
    and `outlet_margin` mm after the outlet cap's z. Returns its volume tag."""
    occ = gmsh.model.occ
    segments, cones, z_out = layout()
    parts = []
    for i, (d, z0, z1) in enumerate(segments):
        z0 -= inlet_margin if i == 0 else 0.0
        z1 += outlet_margin if i == len(segments) - 1 else 0.0
        parts.append((3, occ.addCylinder(0, 0, z0, 0, 0, z1 - z0, d / 2)))
    for z0, z1, d0, d1 in cones:
        parts.append((3, occ.addCone(0, 0, z0, 0, 0, z1 - z0, d0 / 2, d1 / 2)))
    fused, _ = occ.fuse(parts[:1], parts[1:])
    occ.synchronize()
    if len(fused) != 1:
        raise RuntimeError("the fused tube is %d volumes, not one" % len(fused))
    return fused[0][1]


def write_surface_stl(path):
    """The exact stepped tube (margins past the caps included) as an ASCII
    STL, CURVATURE_ELEMENTS triangles around each circumference; returns its
    triangle count."""
    import gmsh  # Debian python3-gmsh

    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("stepped_tube")
        build_geometry(gmsh, INLET_MARGIN, OUTLET_MARGIN)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", CURVATURE_ELEMENTS)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)   # the flat inlet disc and the long 8 mm cylinder
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.model.mesh.generate(2)
        gmsh.write(path)
        _, tags, _ = gmsh.model.mesh.getElements(2)
        return sum(len(t) for t in tags)
    finally:
        gmsh.finalize()


# ---------------------------------------------------------------- meshes

def case_file(M):
    """The scalemesh.toml text for the STL at layer count M."""
    _, _, z_out = layout()
    return """# The stepped tube of validation/multiscale_validation.py (generated).
[input]
file = "%s"

[smoothing]
sweeps = 0              # an exact surface: no voxel steps to smooth out

[sizing]
M = %g
L_min = "0.25 mm"       # below the 1 mm segment's diameter
L_max = "20 mm"

[output]
surface = []

[[openings]]
name = "inlet"
type = "inlet"
point = [0, 0, 0]
normal = [0, 0, -1]

[[openings]]
name = "outlet"
type = "outlet"
point = [0, 0, %g]
normal = [0, 0, 1]

[flow]
viscosity = %g
inlet_speed = %g
""" % (STL_NAME, M, z_out, NU, U_IN)


def fresh_case(case):
    """An empty directory `case` (what was there removed)."""
    if os.path.exists(case):
        shutil.rmtree(case)
    os.makedirs(case)


def scalemesh_case(binary, M, case, stl):
    """A scalemesh run of the STL at layer count M into `case`; returns
    (seconds, report.json's openfoam section)."""
    fresh_case(case)
    shutil.copy(stl, os.path.join(case, STL_NAME))
    with open(os.path.join(case, "scalemesh.toml"), "w") as f:
        f.write(case_file(M))
    t = time.time()
    run([binary, "run", case, "-q"], case, "log.scalemesh")
    seconds = time.time() - t
    with open(os.path.join(case, "report.json")) as f:
        return seconds, json.load(f)["openfoam"]


def gmsh_case(h, case, template):
    """An isotropic Delaunay tet mesh of size h mm of the stepped tube between
    the caps, as an OpenFOAM case with the template's system/, constant/ and
    0/ (the same solver settings and boundary conditions)."""
    import gmsh  # Debian python3-gmsh
    from tube_validation import foam_from_msh

    fresh_case(case)
    for d in ("system", "constant", "0"):
        shutil.copytree(os.path.join(template, d), os.path.join(case, d), ignore=shutil.ignore_patterns("polyMesh"))
    _, _, z_out = layout()
    t = time.time()
    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add("stepped_tube")
        vol = build_geometry(gmsh, 0.0, 0.0)
        groups = {"wall": [], "inlet": [], "outlet": []}
        for dim, tag in gmsh.model.getEntities(2):
            box = gmsh.model.getBoundingBox(dim, tag)
            if box[5] - box[2] > 1e-3:
                groups["wall"].append(tag)
            else:
                groups["inlet" if box[2] < z_out / 2 else "outlet"].append(tag)
        for i, name in enumerate(("wall", "inlet", "outlet")):
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, groups[name], i + 1), name)
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [vol], 10), "fluid")
        gmsh.option.setNumber("Mesh.MeshSizeMin", h)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        gmsh.option.setNumber("Mesh.Algorithm", 6)      # Frontal-Delaunay surfaces
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)    # Delaunay
        gmsh.option.setNumber("Mesh.Optimize", 1)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.model.mesh.generate(3)
        gmsh.write(os.path.join(case, "tube.msh"))
    finally:
        gmsh.finalize()
    foam_from_msh(case, "tube.msh")
    return time.time() - t


def limit_iterations(case, iterations):
    """At most `iterations` SIMPLE iterations, the last one written."""
    path = os.path.join(case, "system", "controlDict")
    text = open(path).read()
    text = re.sub(r"(?m)^(endTime\s+)\S+;", r"\g<1>%d;" % iterations, text)
    text = re.sub(r"(?m)^(writeInterval\s+)\S+;", r"\g<1>%d;" % iterations, text)
    open(path, "w").write(text)


# ---------------------------------------------------------------- analysis

def mesh_faces(case):
    """The polyMesh's points (metres), faces (point index lists) and number of
    interior faces."""
    poly = os.path.join(case, "constant", "polyMesh")
    points = [tuple(float(v) for v in line.strip()[1:-1].split())
              for line in foam_list_lines(os.path.join(poly, "points"))]
    text = open(os.path.join(poly, "faces")).read()
    m = re.search(r"\n(\d+)\s*\n\s*\(", text)
    tokens = text[m.end():].replace("(", " ( ").replace(")", " ) ").split()
    faces, i = [], 0
    while len(faces) < int(m.group(1)):
        n = int(tokens[i])
        faces.append([int(v) for v in tokens[i + 2:i + 2 + n]])
        i += n + 3
    boundary = open(os.path.join(poly, "boundary")).read()
    n_internal = min(int(s) for s in re.findall(r"startFace\s+(\d+)", boundary))
    return points, faces, n_internal


def cells_across(points, faces, n_internal, sections):
    """For each cross-section (z, radius): the cells that diameter lines
    through it pass through (the interior faces a line crosses plus one),
    averaged over LINE_ANGLES, and the boundary faces crossed per line (2
    for a line across a tube). The lines run in the plane z from -1.5 to 1.5
    radii, LINE_OFFSET radii beside the axis."""
    out = []
    for z, radius in sections:
        cut = [[points[i] for i in face] + [k < n_internal]
               for k, face in enumerate(faces)
               if min(points[i][2] for i in face) <= z <= max(points[i][2] for i in face)]
        inner = outer = 0
        for angle in LINE_ANGLES:
            cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
            for face in cut:
                # The face turned by -angle about the axis: the line runs along x.
                ps = [(p[0] * cos + p[1] * sin, p[1] * cos - p[0] * sin, p[2]) for p in face[:-1]]
                if crosses(ps, LINE_OFFSET * radius, z, 1.5 * radius):
                    if face[-1]:
                        inner += 1
                    else:
                        outer += 1
        out.append((1 + inner / len(LINE_ANGLES), outer / len(LINE_ANGLES)))
    return out


def crosses(ps, y, z, half):
    """Whether the polygon `ps` (fanned from its centroid) meets the line
    {(x, y, z): |x| <= half}."""
    c = [sum(p[j] for p in ps) / len(ps) for j in range(3)]
    for a, b in zip(ps, ps[1:] + ps[:1]):
        # Barycentric coordinates of (y, z) in the triangle (c, a, b) projected on yz.
        det = (a[1] - c[1]) * (b[2] - c[2]) - (b[1] - c[1]) * (a[2] - c[2])
        if det == 0:
            continue
        s = ((y - c[1]) * (b[2] - c[2]) - (b[1] - c[1]) * (z - c[2])) / det
        t = ((a[1] - c[1]) * (z - c[2]) - (y - c[1]) * (a[2] - c[2])) / det
        if s >= 0 and t >= 0 and s + t <= 1:
            x = c[0] + s * (a[0] - c[0]) + t * (b[0] - c[0])
            return abs(x) <= half
    return False


def analyse(case):
    """Per segment: wall shear stress, pressure gradient, cross-section and
    cells across against Hagen-Poiseuille at the mesh's flow rate."""
    patches, zmin, _ = boundary_faces(case)
    inlet_area = sum(math.sqrt(sum(x * x for x in a)) for _, a in patches["inlet"])
    Q = U_IN * inlet_area
    time_dir = latest_time(case)
    p = internal_field(os.path.join(time_dir, "p"), 1)
    C = internal_field(os.path.join(time_dir, "C"), 3)
    V = internal_field(os.path.join(time_dir, "V"), 1)
    wss = patch_field(os.path.join(time_dir, "wallShearStress"), "wall", 3)
    wall = patches["wall"]
    if len(wss) != len(wall):
        raise RuntimeError("wallShearStress has %d wall values, the wall %d faces" % (len(wss), len(wall)))

    segments, _, _ = layout()
    ranges = []
    for d, z0, z1 in segments:
        quarter = (z1 - z0) / 4
        ranges.append((d * 0.5e-3, zmin + (z0 + quarter) * 1e-3, zmin + (z1 - quarter) * 1e-3))
    points, faces, n_internal = mesh_faces(case)
    across = cells_across(points, faces, n_internal, [((a + b) / 2, R) for R, a, b in ranges])

    out = []
    for (R, a, b), (n_across, n_boundary) in zip(ranges, across):
        tau_ref = 4 * NU * Q / (math.pi * R ** 3)
        grad_ref = -8 * NU * Q / (math.pi * R ** 4)
        sa = st = sq = 0.0
        for (c, area), t in zip(wall, wss):
            if a <= c[2] <= b:
                mag_a = math.sqrt(sum(x * x for x in area))
                mag_t = math.sqrt(sum(x * x for x in t))
                sa += mag_a
                st += mag_t * mag_a
                sq += (mag_t - tau_ref) ** 2 * mag_a
        # Volume-weighted least-squares line p = p0 + slope z through the
        # cell centres in the range.
        sw = sz = sp = szz = szp = 0.0
        for pi, ci, vi in zip(p, C, V):
            if a <= ci[2] <= b:
                sw += vi
                sz += vi * ci[2]
                sp += vi * pi
                szz += vi * ci[2] ** 2
                szp += vi * ci[2] * pi
        slope = (sw * szp - sz * sp) / (sw * szz - sz * sz)
        out.append({
            "diameter_mm": 2e3 * R, "z_range_mm": [(a - zmin) * 1e3, (b - zmin) * 1e3],
            "cells": sum(1 for ci in C if a <= ci[2] <= b),
            "cells_across": n_across, "boundary_crossings": n_boundary,
            "cross_section_error": sw / (b - a) / (math.pi * R ** 2) - 1,
            "tau_w": st / sa, "tau_w_ref": tau_ref, "wss_error": st / sa / tau_ref - 1,
            "wss_rms_error": math.sqrt(sq / sa) / tau_ref,
            "dpdz": slope, "dpdz_ref": grad_ref, "dpdz_error": slope / grad_ref - 1,
            "reynolds": 4 * Q / (math.pi * NU * 2 * R),
        })
    return {"cells": len(p), "flow_rate_m3s": Q, "inlet_area_mm2": inlet_area * 1e6, "segments": out}


def study_one(mesher, param, case, make_mesh, iterations):
    """Meshes (make_mesh() returns its seconds and extra fields), solves and
    analyses one case; logs a line per segment."""
    mesh_seconds, extra = make_mesh()
    if iterations:
        limit_iterations(case, iterations)
    result = {"mesher": mesher, "parameter": param, "case": case, "mesh_seconds": mesh_seconds}
    result.update(extra)
    result.update(solve(case))
    result.update(analyse(case))
    log("%s %g: %d cells, %s after %d iterations, checkMesh %s"
        % (mesher, param, result["cells"], "converged" if result["converged"] else "NOT converged",
           result["iterations"], "OK" if result["mesh_ok"] else "FAILED"))
    for s in result["segments"]:
        log("  D %g mm: WSS %+.2f%% (rms %.2f%%), dp/dz %+.2f%%, %.1f cells across, cross-section %+.2f%%"
            % (s["diameter_mm"], 100 * s["wss_error"], 100 * s["wss_rms_error"], 100 * s["dpdz_error"],
               s["cells_across"], 100 * s["cross_section_error"]))
    return result


# ---------------------------------------------------------------- report

def table(results):
    """The Markdown table: one row per mesh and segment."""
    rows = ["| mesher | M / h (mm) | cells | D (mm) | segment cells | WSS error | WSS RMS | dp/dz error | "
            "cells across | cross-section error |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        for s in r["segments"]:
            rows.append("| %s | %g | %d | %g | %d | %+.2f%% | %.2f%% | %+.2f%% | %.1f | %+.2f%% |"
                        % (r["mesher"], r["parameter"], r["cells"], s["diameter_mm"], s["cells"],
                           100 * s["wss_error"], 100 * s["wss_rms_error"], 100 * s["dpdz_error"],
                           s["cells_across"], 100 * s["cross_section_error"]))
    return "\n".join(rows)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--scalemesh", default=os.path.join(repo, "build", "src", "cli", "scalemesh"),
                    help="the scalemesh binary (default: %(default)s)")
    ap.add_argument("--workdir", default=os.path.join(repo, "build", "multiscale"),
                    help="case directories (default: %(default)s)")
    ap.add_argument("--out", default=os.path.join(repo, "build", "multiscale", "results.json"),
                    help="results JSON (default: %(default)s)")
    ap.add_argument("--M", type=float, nargs="+", default=DEFAULT_M, help="scalemesh layer counts (default: 5 7 10)")
    ap.add_argument("--gmsh-h", type=float, nargs="*", default=[],
                    help="Gmsh peer: isotropic element sizes in mm (default: none; it needs a scalemesh case "
                    "for its solver settings)")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: M = 5 only, at most %d SIMPLE iterations" % QUICK_ITERATIONS)
    args = ap.parse_args()
    binary = os.path.abspath(args.scalemesh)
    if not os.access(binary, os.X_OK):
        sys.exit("no scalemesh binary at %s (pass --scalemesh)" % binary)
    Ms = [5] if args.quick else args.M
    iterations = QUICK_ITERATIONS if args.quick else None
    os.makedirs(args.workdir, exist_ok=True)
    start = time.time()

    stl = os.path.join(args.workdir, STL_NAME)
    segments, _, z_out = layout()
    log("stepped tube: %s mm, %g mm between the caps, %d STL triangles"
        % (" / ".join("%g" % d for d in DIAMETERS), z_out, write_surface_stl(stl)))
    results = []
    for M in Ms:
        case = os.path.join(args.workdir, "scalemesh-M%g" % M)

        def make_mesh(M=M, case=case):
            seconds, report = scalemesh_case(binary, M, case, stl)
            return seconds, {"max_non_orthogonality_deg": report.get("max_non_orthogonality_deg")}
        results.append(study_one("scalemesh", M, case, make_mesh, iterations))
    for h in args.gmsh_h:
        case = os.path.join(args.workdir, "gmsh-h%g" % h)
        results.append(study_one("gmsh", h, case,
                                 lambda h=h, case=case: (gmsh_case(h, case, results[0]["case"]), {}), iterations))

    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump({"nu": NU, "inlet_speed": U_IN, "diameters_mm": DIAMETERS,
                   "straight_segments_mm": [[z0, z1] for _, z0, z1 in segments], "results": results}, f, indent=1)
    log("\n" + table(results) + "\n")
    log("wrote %s in %.0f s" % (args.out, time.time() - start))
    return 0


if __name__ == "__main__":
    sys.exit(main())
