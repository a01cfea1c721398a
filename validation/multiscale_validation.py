#!/usr/bin/python3
"""Multi-scale flow benchmark: a stepped tube in series or a bifurcating
tree, scalemesh and its peers.

One tube along z made of straight segments of diameters 8, 4, 2 and 1 mm,
each 8 diameters long, joined by conical tapers (each 2 larger diameters
long), is built exactly with Gmsh's OpenCASCADE kernel and its surface
written as a binary STL (CURVATURE_ELEMENTS triangles around each
circumference). scalemesh meshes it at several M (inlet clip plane in the
8 mm segment, outlet in the 1 mm one), with the paper's Delaunay layers or
prism layers (--layers), OpenFOAM's simpleFoam solves laminar flow on each
mesh with the settings scalemesh writes, and each segment's developed middle
(the middle half of its straight length) is compared with Hagen-Poiseuille:
a tube whose feature size spans a factor of 8 should be resolved equally
well in every segment at one M.

--geometry tree: a symmetric planar bifurcating tree instead (Tree: 4
generations, the root 6 mm, each daughter 0.6 of its parent down to
1.3 mm, branches 7 diameters long, daughters at +-30 degrees, cylinders and
a sphere of the parent's diameter at each junction fused by OCC), the inlet
at the root and an [[openings]] plane at each of the 8 leaf ends (outlet_L..,
outlet_R.., the path from the root; each with a radius picking its own
crossing). The outlets all sit at p = 0 and the flow is nearly Stokes, so
every branch of generation g carries about Q / 2^g; each branch's reference
is at the sum of the measured shares of the outlets downstream of it, which
are reported too (how far a mesh breaks the symmetry).

    /usr/bin/python3 validation/multiscale_validation.py            # M = 5 7 10
    /usr/bin/python3 validation/multiscale_validation.py --quick --layers prisms
        # the check CI runs: a coarse STL, M = 7, at most 500 SIMPLE
        # iterations, exit 1 unless every segment is within 5% and M +- 2
    /usr/bin/python3 validation/multiscale_validation.py --only scalemesh \
        --M 5 7 10 14 --layers delaunay prisms --out DIR
        # scalemesh alone; DIR/multiscale_results.json, and its cells for a
        # worst segment within 1% and 2% against the committed peers'
    /usr/bin/python3 validation/multiscale_validation.py --only gmsh gmsh-curvature \
        --gmsh-h 0.8 --gmsh-curvature 20 --out validation
        # Gmsh peers merged into the committed results (a run replaces one
        # of the same mesher and parameter)
    /usr/bin/python3 validation/multiscale_validation.py --from-json \
        validation/multiscale_results.json --doc docs/validation.md \
        --plot docs/multiscale.png    # the sections and plot, nothing run
    /usr/bin/python3 validation/multiscale_validation.py --geometry tree \
        --M 5 10 --gmsh-curvature 16 --mesh3-radius 0.4    # the tree; the
        # CGAL Mesh_3 peers after cmake --build build --target mesh3_surface

It prints Markdown tables (one row per mesh and segment or branch; one per
mesh with the spread of the WSS error over them) and the claim paragraphs,
and merges each run into OUT/multiscale_results.json as soon as it ends
(a run that fails is recorded with its error): per geometry its surface,
flow settings and runs, and a summary of the cells at which each mesher's
worst branch comes within 1% and 2% (null where it does not). A file of
another surface or flow settings is started afresh for that geometry. Runs
go into --workdir (one case directory per mesh, the STL in its root).
--doc PATH puts each geometry's section between its markers (doc_markers)
in the page, appended at its end when it has none; --from-json regenerates
them from a results file. tube_validation.py rewrites the rest of the page
through common.write_page, which keeps these sections as they are.

The peers, each given what it needs to resolve every segment:
  * Gmsh, uniform (--gmsh-h H): isotropic Delaunay tets of size H mm
    everywhere (MeshSizeMin = MeshSizeMax = H, no curvature sizing). H must
    resolve the 1 mm segment, so the 8 mm one gets 8^3 = 512 times the
    cells it would need for as many cells across as the 1 mm one has: the
    cost of a mesher without a scale (and with H = 0.8 mm the 1 mm segment
    is still barely resolved).
  * Gmsh, sized from curvature (--gmsh-curvature N): Gmsh's own
    scale-aware setting, Mesh.MeshSizeFromCurvature = N, the target number
    of elements per 2 pi radians of the CAD curvature: 2 pi R / N on the
    cylinders, cones and cap circles of radius R, so about N elements
    around and N / pi across every segment whatever its diameter, the
    closest isotropic analogue of scalemesh's M. No MeshSizeMin or
    MeshSizeMax (the defaults, 0 and 1e22), so curvature alone sets the
    size; the volume takes it from the boundary (MeshSizeExtendFromBoundary
    = 1, the default). The tets stay isotropic (as long along the axis
    as around) and there are no wall layers. It meshes the exact OCC
    geometry, as the uniform peer does; the other meshers get its STL.
  * snappyHexMesh (--snappy N, the stepped tube only): a background block
    of cubes of 8 / N mm between the caps (its end faces become the inlet
    and outlet patches, as tube_validation.py's snappy_case does for the
    straight tube), a cylindrical refinement region (mode inside) per
    segment after the first, over its straight length and the taper
    leading into it, at the level log2(8 / D), so every segment has about
    N cells across (N = 8: 1 mm cells in the 8 mm segment, 0.125 mm in the
    1 mm one); then castellated and snapped to the scalemesh STL, 3 wall
    layers as in tube_validation.py (relative sizes, expansion ratio 1.2,
    the last layer 0.5 of the cell next to it). Explicit regions rather
    than resolveFeatureAngle or a curvature level: OpenFOAM v1912 has no
    curvature-based surface level (refinementSurfaces' curvatureLevel came
    later; its library here knows only gapLevel), and resolveFeatureAngle
    refines to one maximum level wherever the facets a cell cuts turn by
    more than the angle, which ties the level to the STL's 24 facets
    around rather than to the diameter and refines only at the wall,
    leaving the core to nCellsBetweenLevels. The regions state the intent
    (N across every segment, the hexahedral analogue of M) exactly, as a
    user who knows the diameters would. Not for the tree: its 8 oblique
    outlets cannot be faces of the block (they would need the STL split
    into wall and opening regions, and refinement levels can only halve
    the cell where the tree's diameters shrink by 0.6).
  * CGAL Mesh_3 (validation/mesh3_surface.cpp, built on demand: cmake
    --build build --target mesh3_surface) meshes a closed STL of the
    geometry between its openings (the same OCC model and triangulation as
    the other meshers' STL, without the margins past the openings) as
    Polyhedral_mesh_domain_with_features_3, its sharp edges (the rims of
    the flat opening discs) protected, with mesh3_tube.cpp's criteria:
    facet angle 25 degrees, radius-edge ratio 3, surface distance size /
    20. Patches: the boundary facets on each opening's plane within its
    radius; the rest wall. Two settings:
      - uniform (--mesh3-h H): every size (feature edges, surface
        Delaunay balls, tets' circumradii) H mm, the analogue of Gmsh's
        uniform peer. Not quite uniform: the surface distance bound H / 20
        also shortens the surface edges across the narrow segments (H =
        0.8 mm: about 7 cells across the 1 mm segment, Gmsh's 3);
      - sized from the radius (--mesh3-radius F): size(x) = F r(x), r the
        radius of the centreline segment nearest x (the harness writes the
        centreline: each segment and cone along z, or each branch of the
        tree, with its radii), bounded to [F r_max / 16, F r_max] (inactive
        here), the best a user with a centreline can write: the same mesh
        in every segment, scaled. The size bounds circumradii, so tet edges
        are about 1.6 F r, some 1.2 / F edges along a diameter. Isotropic,
        no wall layers.

Needs: /usr/bin/python3 with the Gmsh Python module (Debian python3-gmsh),
OpenFOAM v1912 (simpleFoam, postProcess, checkMesh; gmshToFoam and
transformPoints for the Gmsh peers; blockMesh and snappyHexMesh for the
snappyHexMesh peer) and a scalemesh binary.

Flow and reference values (kinematic, as OpenFOAM's incompressible solvers
report them): nu = 1e-3 m^2/s as validation/tube_validation.py, a uniform
inlet speed U_IN over the 8 mm inlet cap; the flow rate Q = U_IN x the
mesh's inlet patch area. The Reynolds number 4 Q / (pi nu D) is largest in
the 1 mm segment, about 3, so the entrance length (about 0.06 Re D, plus a
diameter of creeping-flow adjustment) is short against each segment's
straight length. For a segment of radius R:
    wall shear stress   tau_w / rho  = 4 nu Q / (pi R^3)
    pressure gradient  -dp/dz / rho  = 8 nu Q / (pi R^4)
The tree: U_IN over the 6 mm root, Reynolds number 0.3 at the root and
smaller downstream (Q halves, D shrinks by 0.6); each branch at its share
Q / 2^g. Measured per segment or branch: the area-weighted mean
|wallShearStress| of the wall faces whose centres lie in the middle half
(and within 1.5 radii of the axis), its local RMS deviation from tau_w, the
slope of the volume-weighted least-squares line through the cell
centres' pressures there, the cells across a diameter (cells_across: each
cell a diameter line passes through adds its chord over its own extent
along the line, so that a layer counts 1 however many tets it is split
into; averaged over 4 lines 45 degrees apart) and the cells the line passes
through, and the mesh's cross-section (cell volume / length) against
pi R^2. The WSS and dp/dz errors are given twice: against the exact radius,
and against the radius of a circle of the mesh's own cross-section there
(what the surface's facets and the mesh take from the area left out). Per
mesh, the share of the inlet's flow rate through each outlet.
"""

import argparse
import fcntl
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (REPO, have_gnuplot, write_series, run_gnuplot,  # noqa: E402
                    cpu_model, log, run, solve, latest_time, internal_field,  # noqa: E402
                    patch_field, boundary_faces, read_polymesh, replace_section, snappy_tube)
from tube_validation import case_from_template, cells_for, foam_from_msh, gmsh_volume_case  # noqa: E402
from netgen_peer import netgen_case  # noqa: E402

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
# The tree (--geometry tree): generations, root diameter (mm), daughter /
# parent diameter ratio, branch length in its diameters, the angle of each
# daughter from its parent's direction (degrees).
TREE_GENERATIONS = 4
TREE_ROOT = 6.0
TREE_RATIO = 0.6
TREE_LENGTH = 7.0
TREE_ANGLE = 30.0
STL_NAME = "surface.stl"
# Surface triangles around a circumference. The inscribed polygon's area
# falls short of the circle's by about (2 pi / n)^2 / 6: 1.1% at 24 (which
# raises the mean WSS by some 1.7%), 0.16% at 64 (0.24%); the "own section"
# errors leave it out. 64 makes 128k triangles of the stepped tube and
# 343k of the tree (binary STL).
CURVATURE_ELEMENTS = 64
QUICK_CURVATURE_ELEMENTS = 32      # --quick: 33k triangles of the stepped tube
RESULTS_NAME = "multiscale_results.json"

DEFAULT_M = [5, 7, 10]
# The meshers: a name for the page, what their parameter is, its symbol
# (also the case directory's prefix before its value).
MESHERS = {
    "scalemesh": ("scalemesh", "layers across every cross-section (the paper's Delaunay layers)", "M"),
    "scalemesh-prisms": ("scalemesh, prism layers", "layers across every cross-section, layers = \"prisms\"", "M"),
    "gmsh": ("Gmsh, uniform", "element size everywhere (mm)", "h"),
    "gmsh-curvature": ("Gmsh, sized from curvature", "elements per 2 pi radians of curvature", "N"),
    "snappy": ("snappyHexMesh, a level per segment", "cells across every segment", "N"),
    "mesh3": ("CGAL Mesh_3, uniform", "size bound everywhere (mm): edges, surface balls, tet circumradii", "h"),
    "mesh3-radius": ("CGAL Mesh_3, sized from the radius",
                     "size bound as a fraction of the local radius, from the centreline", "F"),
    "netgen-curvature": ("Netgen, sized from curvature, 3 prism layers",
                         "h <= r / F along the STL's curvature (about 2 pi F elements around)", "F"),
}
# The keys of the results file's summary: each mesher's name and setting.
SUMMARY_NAMES = {"scalemesh": "scalemesh", "scalemesh-prisms": "scalemesh prisms", "gmsh": "gmsh uniform",
                 "gmsh-curvature": "gmsh curvature", "snappy": "snappyhexmesh levels", "mesh3": "mesh_3 uniform",
                 "mesh3-radius": "mesh_3 radius field", "netgen-curvature": "netgen curvature"}
QUICK_ITERATIONS = 500
QUICK_M = 7                        # --quick: scalemesh at this M
QUICK_WSS = 0.05                   # --quick: every branch's mean WSS within 5% of Hagen-Poiseuille
QUICK_ACROSS = 2                   # and M +- 2 cells across it
AS_GOOD = 1.25                     # a ratio below which two figures are "about the same"
GOAL = 3.0                         # scalemesh's goal: this many times fewer cells than every peer
LINE_ANGLES = [0, 45, 90, 135]     # degrees from x of the diameter lines counted in each cross-section
LINE_OFFSET = 0.0123               # their distance from the axis, in radii: off any symmetry of the mesh
NETGEN_MAXH = 0.25                 # Netgen's size bound, in inlet diameters: loose, so curvature sets the size
PLANE_OFFSET = 0.0217              # the cross-section's distance from the middle, in radii: off a hex mesh's faces


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


def along(p, t, s):
    """The point p + s t."""
    return tuple(pi + s * ti for pi, ti in zip(p, t))


def fuse_volumes(gmsh, parts):
    """The OCC volumes `parts` ((3, tag) pairs) fused into one; its tag."""
    fused, _ = gmsh.model.occ.fuse(parts[:1], parts[1:])
    gmsh.model.occ.synchronize()
    if len(fused) != 1:
        raise RuntimeError("the fused geometry is %d volumes, not one" % len(fused))
    return fused[0][1]


class SteppedTube:
    """The stepped tube: straight segments of DIAMETERS along z in series,
    joined by cones, the inlet cap at z = 0 in the widest one."""
    name = "stepped"
    title = "multi-scale stepped tube"
    piece, pieces = "segment", "segments"
    inlet_diameter = DIAMETERS[0]

    def description(self):
        """The geometry paragraph of the page."""
        return ("One tube, straight segments of diameters %s mm in series (each %g diameters long, joined by "
                "cones %g larger diameters long)" % (", ".join("%g" % d for d in DIAMETERS), SEGMENT_DIAMETERS,
                                                     TAPER_DIAMETERS))

    def build(self, gmsh, margins):
        """The tube as one OCC volume in the current Gmsh model: cylinders and
        cones fused, flat discs at the ends, with `margins` INLET_MARGIN mm
        before z = 0 and OUTLET_MARGIN mm after the outlet cap. Its tag."""
        occ = gmsh.model.occ
        segments, cones, _ = layout()
        parts = []
        for i, (d, z0, z1) in enumerate(segments):
            z0 -= INLET_MARGIN if margins and i == 0 else 0.0
            z1 += OUTLET_MARGIN if margins and i == len(segments) - 1 else 0.0
            parts.append((3, occ.addCylinder(0, 0, z0, 0, 0, z1 - z0, d / 2)))
        for z0, z1, d0, d1 in cones:
            parts.append((3, occ.addCone(0, 0, z0, 0, 0, z1 - z0, d0 / 2, d1 / 2)))
        return fuse_volumes(gmsh, parts)

    def centreline(self):
        """(start, end, r0, r1) of each straight segment and cone between
        the caps, mm."""
        segments, cones, _ = layout()
        return ([((0, 0, z0), (0, 0, z1), d / 2, d / 2) for d, z0, z1 in segments]
                + [((0, 0, z0), (0, 0, z1), d0 / 2, d1 / 2) for z0, z1, d0, d1 in cones])

    def openings(self):
        """(name, type, point, outward normal, radius) of the clip planes, mm."""
        _, _, z_out = layout()
        return [("inlet", "inlet", (0, 0, 0), (0, 0, -1), 0), ("outlet", "outlet", (0, 0, z_out), (0, 0, 1), 0)]

    def branches(self):
        """The measured pieces: label, diameter (mm), the ends of the middle
        half of the straight length (mm) and the share of the flow rate."""
        segments, _, _ = layout()
        out = []
        for d, z0, z1 in segments:
            quarter = (z1 - z0) / 4
            out.append({"label": "segment %d" % (len(out) + 1), "path": "", "diameter": d, "a": (0, 0, z0 + quarter),
                        "b": (0, 0, z1 - quarter), "flow_fraction": 1.0})
        return out


class Tree:
    """A symmetric planar bifurcating tree in the xz plane: the root along z
    from the inlet cap at the origin, each branch splitting into two at
    +-TREE_ANGLE from its direction, TREE_GENERATIONS generations, the
    daughters TREE_RATIO of the parent's diameter, each branch TREE_LENGTH
    diameters long, a sphere of the parent's diameter at each junction."""
    name = "tree"
    title = "multi-scale bifurcating tree"
    piece, pieces = "branch", "branches"
    inlet_diameter = TREE_ROOT

    def description(self):
        """The geometry paragraph of the page."""
        d = [TREE_ROOT * TREE_RATIO ** g for g in range(TREE_GENERATIONS)]
        return ("A symmetric planar bifurcating tree of %d generations (%d branches, %d outlets): diameters %s mm "
                "(each daughter %g of its parent), each branch %g diameters long, daughters at +-%g degrees from "
                "the parent's direction, cylinders fused with a sphere of the parent's diameter at each junction; "
                "each branch of generation g carries Q / 2^g"
                % (TREE_GENERATIONS, 2 ** TREE_GENERATIONS - 1, 2 ** (TREE_GENERATIONS - 1),
                   ", ".join("%.3g" % x for x in d), TREE_RATIO, TREE_LENGTH, TREE_ANGLE))

    def layout(self):
        """The branches, root first, depth first: dicts with label (L/R path
        from the root), generation, diameter, start, end and direction (mm)."""
        out = []

        def grow(label, generation, start, angle):
            d = TREE_ROOT * TREE_RATIO ** generation
            t = (math.sin(math.radians(angle)), 0.0, math.cos(math.radians(angle)))
            end = along(start, t, TREE_LENGTH * d)
            out.append({"label": label, "generation": generation, "diameter": d, "start": start, "end": end,
                        "direction": t})
            if generation + 1 < TREE_GENERATIONS:
                grow(label + "L", generation + 1, end, angle - TREE_ANGLE)
                grow(label + "R", generation + 1, end, angle + TREE_ANGLE)
        grow("", 0, (0.0, 0.0, 0.0), 0.0)
        return out

    def build(self, gmsh, margins):
        """The tree as one OCC volume: a cylinder per branch (with `margins`,
        the root INLET_MARGIN mm longer before the inlet, the leaves
        OUTLET_MARGIN mm longer past their outlets) and a sphere at each
        junction, fused. Its tag."""
        occ = gmsh.model.occ
        parts = []
        for b in self.layout():
            leaf = b["generation"] == TREE_GENERATIONS - 1
            start = along(b["start"], b["direction"], -INLET_MARGIN if margins and not b["label"] else 0.0)
            end = along(b["end"], b["direction"], OUTLET_MARGIN if margins and leaf else 0.0)
            parts.append((3, occ.addCylinder(*start, *[e - s for e, s in zip(end, start)], b["diameter"] / 2)))
            if not leaf:
                parts.append((3, occ.addSphere(*b["end"], b["diameter"] / 2)))
        return fuse_volumes(gmsh, parts)

    def centreline(self):
        """(start, end, r, r) of each branch, mm."""
        return [(b["start"], b["end"], b["diameter"] / 2, b["diameter"] / 2) for b in self.layout()]

    def openings(self):
        """The inlet at the root's start, an outlet at each leaf's end, each
        plane's crossing picked within a leaf diameter of its centre."""
        out = [("inlet", "inlet", (0, 0, 0), (0, 0, -1), 0)]
        for b in self.layout():
            if b["generation"] == TREE_GENERATIONS - 1:
                out.append(("outlet_" + b["label"], "outlet", b["end"], b["direction"], b["diameter"]))
        return out

    def branches(self):
        """As SteppedTube.branches: the middle half of every branch."""
        out = []
        for b in self.layout():
            quarter = TREE_LENGTH * b["diameter"] / 4
            out.append({"label": "g%d %s" % (b["generation"], b["label"] or "root"), "path": b["label"],
                        "diameter": b["diameter"],
                        "a": along(b["start"], b["direction"], quarter), "b": along(b["end"], b["direction"], -quarter),
                        "flow_fraction": 0.5 ** b["generation"]})
        return out


GEOMETRIES = {g.name: g for g in (SteppedTube(), Tree())}


def write_surface_stl(geometry, path, elements, margins=True):
    """The exact geometry (with `margins`, running on past the openings) as
    a binary STL, `elements` triangles around each circumference; returns
    its triangle count."""
    import gmsh  # Debian python3-gmsh

    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(geometry.name)
        geometry.build(gmsh, margins)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", elements)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)   # flat discs and long wide cylinders
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.model.mesh.generate(2)
        gmsh.write(path)
        _, tags, _ = gmsh.model.mesh.getElements(2)
        return sum(len(t) for t in tags)
    finally:
        gmsh.finalize()


# ---------------------------------------------------------------- meshes

def case_file(geometry, M, layers="delaunay"):
    """The scalemesh.toml text for the geometry's STL at layer count M, its
    wall layers `layers` ("delaunay" or "prisms")."""
    openings = "".join(
        "\n[[openings]]\nname = \"%s\"\ntype = \"%s\"\npoint = [%.9g, %.9g, %.9g]\nnormal = [%.9g, %.9g, %.9g]\n%s"
        % ((name, kind) + tuple(round(v, 9) + 0.0 for v in point + normal)
           + ("radius = %g\n" % radius if radius else "",))
        for name, kind, point, normal, radius in geometry.openings())
    return """# The %s of validation/multiscale_validation.py (generated).
[input]
file = "%s"

[smoothing]
sweeps = 0              # an exact surface: no voxel steps to smooth out

[sizing]
M = %g
L_min = "0.25 mm"       # below the smallest diameter
L_max = "20 mm"

[volume]
layers = "%s"

[output]
surface = []
%s
[flow]
viscosity = %g
inlet_speed = %g
""" % (geometry.title, STL_NAME, M, layers, openings, NU, U_IN)


def fresh_case(case):
    """An empty directory `case` (what was there removed)."""
    if os.path.exists(case):
        shutil.rmtree(case)
    os.makedirs(case)


def scalemesh_case(binary, geometry, M, case, stl, layers="delaunay"):
    """A scalemesh run of the geometry's STL at layer count M, wall layers
    `layers`, into `case`; returns (seconds, report.json's openfoam
    section)."""
    fresh_case(case)
    shutil.copy(stl, os.path.join(case, STL_NAME))
    with open(os.path.join(case, "scalemesh.toml"), "w") as f:
        f.write(case_file(geometry, M, layers))
    t = time.time()
    run([binary, "run", case, "-q"], case, "log.scalemesh")
    seconds = time.time() - t
    with open(os.path.join(case, "report.json")) as f:
        return seconds, json.load(f)["openfoam"]


def gmsh_uniform(h):
    """Gmsh options for isotropic tets of size h mm everywhere."""
    return {"Mesh.MeshSizeMin": h, "Mesh.MeshSizeMax": h, "Mesh.MeshSizeFromCurvature": 0}


def gmsh_curvature(n):
    """Gmsh options for element sizes from the CAD curvature: n elements per
    2 pi radians, so 2 pi R / n on a tube of radius R and its cap circle,
    spread into the volume from the boundary; no lower or upper bound."""
    return {"Mesh.MeshSizeFromCurvature": n, "Mesh.MeshSizeExtendFromBoundary": 1}


def gmsh_case(geometry, options, case, template):
    """A Delaunay tet mesh (the Gmsh size `options`) of the exact geometry
    between its openings, as an OpenFOAM case with the template's system/,
    constant/ and 0/ (the same solver settings and boundary conditions)."""
    def build(gmsh):
        vol = geometry.build(gmsh, False)
        # An opening's disc is the surface whose bounding box is centred on
        # the opening's point; the rest is wall.
        groups = {name: [] for name in ["wall"] + [o[0] for o in geometry.openings()]}
        for dim, tag in gmsh.model.getEntities(2):
            box = gmsh.model.getBoundingBox(dim, tag)
            centre = [(box[k] + box[k + 3]) / 2 for k in range(3)]
            name = "wall"
            for opening, _, point, _, _ in geometry.openings():
                if math.dist(centre, point) < 1e-3:
                    name = opening
            groups[name].append(tag)
        for name, tags in groups.items():
            if len(tags) != 1 and name != "wall":
                raise RuntimeError("opening %s is %d surfaces of the Gmsh model" % (name, len(tags)))
        return vol, groups
    return gmsh_volume_case(case, template, build, options)


def mesh3_case(geometry, binary, size_args, case, template, stl):
    """A CGAL Mesh_3 mesh (validation/mesh3_surface.cpp, `size_args` its
    sizing arguments) of `stl`, the geometry between its openings, as an
    OpenFOAM case with the template's system/, constant/ and 0/ as for
    Gmsh; the centreline file its radius sizing reads written into the
    case. Returns the seconds."""
    case_from_template(case, template)
    with open(os.path.join(case, "centreline.txt"), "w") as f:
        for a, b, r0, r1 in geometry.centreline():
            f.write(" ".join("%.9g" % v for v in (*a, *b, r0, r1)) + "\n")
    openings = []
    for name, _, point, normal, radius in geometry.openings():
        # Openings without a radius (one crossing of their plane): the
        # inlet's diameter, wider than the crossing.
        openings += ["--opening", name] + ["%.9g" % v for v in (*point, *normal, radius or geometry.inlet_diameter)]
    t = time.time()
    run([binary, stl, "tube.msh"] + size_args + openings, case, "log.mesh3_surface")
    foam_from_msh(case, "tube.msh")
    return time.time() - t


def mesh3_sizes(geometry, mesher, param):
    """mesh3_surface's sizing arguments: --size H (uniform), or the radius
    factor F with the centreline and the bound F r_max."""
    if mesher == "mesh3":
        return ["--size", "%g" % param]
    r_max = max(max(r0, r1) for _, _, r0, r1 in geometry.centreline())
    return ["--size", "%g" % (param * r_max), "--radius-factor", "%g" % param, "--centreline", "centreline.txt"]


def snappy_levels(n):
    """The snappyHexMesh sizes for about n cells across every segment: the
    background cell h = (largest diameter) / n mm and, per segment after the
    first, (level, z0, z1, radius) of a cylindrical refinement region (mm)
    over its straight length and the taper leading into it, one background
    cell wider than the taper's larger end, at the level that halves h once
    per halving of the diameter."""
    segments, cones, _ = layout()
    h = DIAMETERS[0] / n
    regions = []
    for (d, _, z1), (c0, _, d0, _) in zip(segments[1:], cones):
        regions.append((int(round(math.log2(DIAMETERS[0] / d))), c0, z1, d0 / 2 + h))
    return h, regions


def snappy_case(n, case, template, stl, layers=3):
    """A snappyHexMesh mesh of the stepped tube between the caps, about n
    cells across every segment (snappy_levels): a background block of h mm
    cubes from the inlet cap to the outlet cap (its end faces become the
    inlet and outlet patches, as in tube_validation.py), castellated and
    snapped to the same STL as scalemesh's, the segments refined by regions,
    then `layers` wall layers with tube_validation.py's settings (relative
    sizes, expansion ratio 1.2, the last layer 0.5 of the cell next to it);
    the template's system/, constant/ and 0/ as for Gmsh."""
    case_from_template(case, template)
    os.makedirs(os.path.join(case, "constant", "triSurface"))
    shutil.copy(stl, os.path.join(case, "constant", "triSurface", STL_NAME))
    _, _, z_out = layout()
    h, regions = snappy_levels(n)
    seconds, layers_made, thickness = snappy_tube(case, STL_NAME, 0.0, z_out, DIAMETERS[0] / 2, h,
                                                  SEGMENT_DIAMETERS * DIAMETERS[0] / 2 + 0.0345, layers, regions)
    log("snappyHexMesh n %g: %g wall layers on average, %g%% of the asked thickness" % (n, layers_made, thickness))
    return seconds, {"snappy_layers": layers_made, "snappy_thickness_percent": thickness}


def limit_iterations(case, iterations):
    """At most `iterations` SIMPLE iterations, the last one written."""
    path = os.path.join(case, "system", "controlDict")
    text = open(path).read()
    text = re.sub(r"(?m)^(endTime\s+)\S+;", r"\g<1>%d;" % iterations, text)
    text = re.sub(r"(?m)^(writeInterval\s+)\S+;", r"\g<1>%d;" % iterations, text)
    open(path, "w").write(text)


# ---------------------------------------------------------------- analysis

def frame(a, b):
    """An orthonormal frame (e1, e2, t) with t along a -> b and e2 = y x t
    normalised (for a tube along z: x, y, z)."""
    t = [bi - ai for ai, bi in zip(a, b)]
    n = math.sqrt(sum(v * v for v in t))
    t = [v / n for v in t]
    e1 = [t[2], 0.0, -t[0]]          # y x t
    n = math.sqrt(sum(v * v for v in e1))
    e1 = [v / n for v in e1]
    e2 = [t[1] * e1[2] - t[2] * e1[1], t[2] * e1[0] - t[0] * e1[2], t[0] * e1[1] - t[1] * e1[0]]
    return e1, e2, t


def local(p, origin, axes):
    """p's coordinates in the frame `axes` at `origin`."""
    d = [pi - oi for pi, oi in zip(p, origin)]
    return tuple(sum(di * ai for di, ai in zip(d, axis)) for axis in axes)


def cells_across(mesh, sections):
    """For each cross-section (centre, frame axes, radius) of the polyMesh
    `mesh` (read_polymesh): how many cells thick the mesh is along diameter
    lines in it, averaged over LINE_ANGLES. Each line runs in the plane from
    -1.5 to 1.5 radii, LINE_OFFSET radii beside the axis; the plane lies
    PLANE_OFFSET radii along the axis from the centre, off the face planes
    of a hexahedral mesh. A cell the line passes through adds its chord
    (from the first to the last of its faces the line crosses) over its own
    extent along the line: a layer of prisms, or of the tets a prism splits
    into, adds 1 however many of its cells the line passes through; a layer
    of hexahedra adds 1; isotropic tets add about the diameter over their
    mean extent. Returns per section a dict: "across" (that sum), "crossed"
    (the cells the line passes through), "boundary" (the boundary faces a
    line crosses: 2 across a tube; the lines where it is not are counted in
    "odd_lines")."""
    points, faces, owner, neighbour = mesh
    n_internal = len(neighbour)
    out = []
    for centre, axes, radius in sections:
        origin = [c + PLANE_OFFSET * radius * t for c, t in zip(centre, axes[2])]
        height = [sum((p[j] - origin[j]) * axes[2][j] for j in range(3)) for p in points]
        cut = [k for k, face in enumerate(faces)
               if min(height[i] for i in face) < 0 < max(height[i] for i in face)]
        flat = {i: local(points[i], origin, axes) for k in cut for i in faces[k]}
        lines = []          # per angle: {cell: (x_first, x_last)} and the boundary crossings
        for angle in LINE_ANGLES:
            cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
            chords, walls = {}, set()
            for k in cut:
                # The face turned by -angle about the axis: the line runs along x.
                ps = [(p[0] * cos + p[1] * sin, p[1] * cos - p[0] * sin, p[2]) for p in (flat[i] for i in faces[k])]
                x = crossing(ps, LINE_OFFSET * radius, 0.0, 1.5 * radius)
                if x is None:
                    continue
                if k >= n_internal:
                    walls.add(round(x / radius, 9))
                for c in ((owner[k], neighbour[k]) if k < n_internal else (owner[k],)):
                    lo, hi = chords.get(c, (x, x))
                    chords[c] = (min(lo, x), max(hi, x))
            lines.append((angle, chords, len(walls)))
        # Each cell's points, for its extent along a line.
        wanted = {c for _, chords, _ in lines for c in chords}
        cell_points = {c: set() for c in wanted}
        for k, c in enumerate(owner):
            if c in wanted:
                cell_points[c].update(faces[k])
        for k, c in enumerate(neighbour):
            if c in wanted:
                cell_points[c].update(faces[k])
        across = crossed = boundary = 0.0
        odd = 0
        for angle, chords, walls in lines:
            direction = [math.cos(math.radians(angle)) * a + math.sin(math.radians(angle)) * b
                         for a, b in zip(axes[0], axes[1])]
            for c, (lo, hi) in chords.items():
                if hi <= lo:
                    continue        # touched at one point only
                s = [sum(points[i][j] * direction[j] for j in range(3)) for i in cell_points[c]]
                across += (hi - lo) / (max(s) - min(s))
                crossed += 1
            boundary += walls
            odd += walls != 2
        n = len(LINE_ANGLES)
        out.append({"across": across / n, "crossed": crossed / n, "boundary": boundary / n, "odd_lines": odd})
    return out


def crossing(ps, y, z, half):
    """Where the polygon `ps` (fanned from its centroid) meets the line
    {(x, y, z): |x| <= half}: its x, or None. Each fan triangle is
    half-open (two of its edges in, one out), so that a line through an
    edge shared by two of them meets one."""
    c = [sum(p[j] for p in ps) / len(ps) for j in range(3)]
    if (c[1], c[2]) == (y, z):   # through the centroid, which no half-open fan triangle holds
        return c[0] if abs(c[0]) <= half else None
    for a, b in zip(ps, ps[1:] + ps[:1]):
        # Barycentric coordinates of (y, z) in the triangle (c, a, b) projected on yz.
        det = (a[1] - c[1]) * (b[2] - c[2]) - (b[1] - c[1]) * (a[2] - c[2])
        if det == 0:
            continue
        s = ((y - c[1]) * (b[2] - c[2]) - (b[1] - c[1]) * (z - c[2])) / det
        t = ((a[1] - c[1]) * (z - c[2]) - (y - c[1]) * (a[2] - c[2])) / det
        if s >= 0 and t > 0 and s + t <= 1:
            x = c[0] + s * (a[0] - c[0]) + t * (b[0] - c[0])
            return x if abs(x) <= half else None
    return None


def patch_flux(path, patch, n_faces):
    """The sum of the face values of `patch` in the surface scalar field at
    `path` (phi: the volume flux out through it, m^3/s), its value written
    as a uniform value or a list on one or several lines."""
    text = open(path).read()
    m = re.search(r"\n\s*%s\s*\{[^}]*?value\s+(?:uniform\s+([^;\s]+)|nonuniform\s+List<scalar>\s*(\d+)\s*\(([^)]*)\))"
                  % re.escape(patch), text)
    if not m:
        raise RuntimeError("no value of patch %s in %s" % (patch, path))
    if m.group(1) is not None:
        return float(m.group(1)) * n_faces
    values = [float(v) for v in m.group(3).split()]
    if len(values) != int(m.group(2)):
        raise RuntimeError("patch %s of %s: %d values of %s read" % (patch, path, len(values), m.group(2)))
    return sum(values)


def branch_shares(geometry, outlet_shares):
    """Each branch's share of the inlet's flow rate: the sum of the measured
    shares of the outlets downstream of it (for every segment of the
    stepped tube, its single outlet's measured share)."""
    out = []
    for b in geometry.branches():
        downstream = [share for name, share in outlet_shares.items() if name.startswith("outlet_" + b["path"])
                      or name == "outlet"]
        out.append(sum(downstream))
    return out


def analyse(geometry, case):
    """Per branch (segment) of the geometry: wall shear stress, pressure
    gradient, cross-section and cells across against Hagen-Poiseuille at its
    measured share of the mesh's flow rate (branch_shares), over the middle
    half of its straight length (the wall faces and cells whose centres
    project onto it and lie within 1.5 radii of its axis). The errors are
    against the exact radius and, as "own", against the radius of a circle
    of the mesh's own cross-section there: the latter leaves out what the
    surface's facets and the mesh's wall take from the area."""
    patches, _, _ = boundary_faces(case)
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
    shares = {name: patch_flux(os.path.join(time_dir, "phi"), name, len(patches[name])) / Q
              for name, kind, _, _, _ in geometry.openings() if kind == "outlet"}

    pieces = []
    for b, share in zip(geometry.branches(), branch_shares(geometry, shares)):
        a, e = [v * 1e-3 for v in b["a"]], [v * 1e-3 for v in b["b"]]
        pieces.append((b, share, a, e, frame(a, e), math.dist(a, e), b["diameter"] * 0.5e-3))
    across = cells_across(read_polymesh(case), [([(ai + ei) / 2 for ai, ei in zip(a, e)], axes, R)
                                                for _, _, a, e, axes, _, R in pieces])

    out = []
    for (b, share, a, _, axes, length, R), lines in zip(pieces, across):
        def inside(c):
            """The position of c along the axis, or None when c is not in the piece."""
            x, y, s = local(c, a, axes)
            return s if 0 <= s <= length and x * x + y * y <= (1.5 * R) ** 2 else None
        q = Q * share
        sa = st = 0.0
        taus = []
        for (c, area), t in zip(wall, wss):
            if inside(c) is not None:
                mag_a = math.sqrt(sum(x * x for x in area))
                mag_t = math.sqrt(sum(x * x for x in t))
                sa += mag_a
                st += mag_t * mag_a
                taus.append((mag_t, mag_a))
        # Volume-weighted least-squares line p = p0 + slope s through the
        # cell centres in the piece, s along its axis.
        n = sw = sz = sp = szz = szp = 0.0
        for pi, ci, vi in zip(p, C, V):
            s = inside(ci)
            if s is not None:
                n += 1
                sw += vi
                sz += vi * s
                sp += vi * pi
                szz += vi * s ** 2
                szp += vi * s * pi
        slope = (sw * szp - sz * sp) / (sw * szz - sz * sz)
        area = sw / length
        R_own = math.sqrt(area / math.pi)
        tau_ref, tau_own = (4 * NU * q / (math.pi * r ** 3) for r in (R, R_own))
        grad_ref, grad_own = (-8 * NU * q / (math.pi * r ** 4) for r in (R, R_own))
        out.append({
            "label": b["label"], "diameter_mm": 2e3 * R, "from_mm": list(b["a"]), "to_mm": list(b["b"]),
            "flow_fraction": share, "flow_fraction_symmetric": b["flow_fraction"], "cells": int(n),
            "cells_across": lines["across"], "cells_crossed": lines["crossed"],
            "boundary_crossings": lines["boundary"], "odd_lines": lines["odd_lines"],
            "cross_section_error": area / (math.pi * R ** 2) - 1,
            "tau_w": st / sa, "tau_w_ref": tau_ref, "wss_error": st / sa / tau_ref - 1,
            "wss_error_own": st / sa / tau_own - 1,
            "wss_rms_error": math.sqrt(sum((t - tau_ref) ** 2 * w for t, w in taus) / sa) / tau_ref,
            "dpdz": slope, "dpdz_ref": grad_ref, "dpdz_error": slope / grad_ref - 1,
            "dpdz_error_own": slope / grad_own - 1,
            "reynolds": 4 * q / (math.pi * NU * 2 * R),
        })
    return {"cells": len(p), "flow_rate_m3s": Q, "inlet_area_mm2": inlet_area * 1e6, "outlet_flow_fractions": shares,
            "segments": out}


def study_one(geometry, mesher, param, case, make_mesh, iterations):
    """Meshes (make_mesh() returns its seconds and extra fields), solves and
    analyses one case of the geometry; logs a line per branch (segment).
    A run that fails anywhere is returned with its error as "failed"."""
    result = {"mesher": mesher, "parameter": param, "case": case}
    try:
        result["mesh_seconds"], extra = make_mesh()
        result.update(extra)
        if iterations:
            limit_iterations(case, iterations)
        result.update(solve(case))
        result.update(analyse(geometry, case))
    except Exception as e:  # noqa: BLE001 -- any failure of one run (Gmsh raises plain Exception) is its result
        result["failed"] = ("%s: %s" % (type(e).__name__, e))[-2000:]
        log("%s %g FAILED: %s" % (mesher, param, result["failed"]))
        return result
    log("%s %g: %d cells, %s after %d iterations, checkMesh %s"
        % (mesher, param, result["cells"], "converged" if result["converged"] else "NOT converged",
           result["iterations"], "OK" if result["mesh_ok"] else "FAILED"))
    for s in result["segments"]:
        log("  %s (D %.3g mm, %.3f of Q): WSS %+.2f%% (own section %+.2f%%, rms %.2f%%), dp/dz %+.2f%%, "
            "%.1f cells across (%.1f crossed%s), cross-section %+.2f%%"
            % (s["label"], s["diameter_mm"], s["flow_fraction"], 100 * s["wss_error"], 100 * s["wss_error_own"],
               100 * s["wss_rms_error"], 100 * s["dpdz_error"], s["cells_across"], s["cells_crossed"],
               ", %d lines not 2 walls" % s["odd_lines"] if s["odd_lines"] else "", 100 * s["cross_section_error"]))
    return result


# ---------------------------------------------------------------- report

def done(results):
    """The runs that did not fail."""
    return [r for r in results if "failed" not in r]


def table(results):
    """The Markdown table: one row per mesh and branch (segment); a failed
    run is one row saying so."""
    rows = ["| mesher | parameter | cells | segment / branch | D (mm) | share of Q | its cells | WSS error | "
            "WSS error, own section | WSS RMS | dp/dz error | cells across | cells crossed | cross-section error |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        name = "| %s | %s %g |" % (r["mesher"], MESHERS[r["mesher"]][2], r["parameter"])
        if "failed" in r:
            message = r["failed"].strip().splitlines()[-1][:200].replace("|", "/") if r["failed"].strip() else ""
            rows.append("%s failed: %s%s" % (name, message or "(no message)", " |" * 12))
            continue
        for s in r["segments"]:
            rows.append("%s %d | %s | %.3g | %.4f | %d | %+.2f%% | %+.2f%% | %.2f%% | %+.2f%% | %.1f | %.1f%s | %+.2f%% |"
                        % (name, r["cells"], s["label"], s["diameter_mm"], s["flow_fraction"], s["cells"],
                           100 * s["wss_error"], 100 * s["wss_error_own"], 100 * s["wss_rms_error"],
                           100 * s["dpdz_error"], s["cells_across"], s["cells_crossed"],
                           " (%d of %d lines not across 2 walls)" % (s["odd_lines"], len(LINE_ANGLES))
                           if s["odd_lines"] else "", 100 * s["cross_section_error"]))
    return "\n".join(rows)


def spread(result, key="wss_error"):
    """max - min of an error over the branches, as a fraction."""
    errors = [s[key] for s in result["segments"]]
    return max(errors) - min(errors)


def worst(result, key="wss_error"):
    """The largest |error| over the branches."""
    return max(abs(s[key]) for s in result["segments"])


def across_range(result):
    """The mean cells across the widest and across the narrowest branches."""
    out = []
    for pick in (max, min):
        d = pick(s["diameter_mm"] for s in result["segments"])
        n = [s["cells_across"] for s in result["segments"] if abs(s["diameter_mm"] - d) < 1e-6 * d]
        out.append(sum(n) / len(n))
    return out


def cells_for_worst(results, target):
    """Per mesher (its SUMMARY_NAMES name): the cells at which its worst
    branch's |WSS error| falls to `target` and stays below (log-log
    interpolated between its meshes, tube_validation.cells_for): a number
    when its meshes bracket the level or its coarsest is already below it
    (then its cell count, an upper bound; `how` says which), None when its
    finest is still above it."""
    out = {}
    for mesher in MESHERS:
        runs = [{"cells": r["cells"], "worst": worst(r)} for r in done(results) if r["mesher"] == mesher]
        if runs:
            value, how = cells_for(runs, "worst", target)
            out[SUMMARY_NAMES[mesher]] = (None if how == "above" else round(value), how)
    return out


def summary(data):
    """The results file's summary: for 1% and 2%, per mesher and geometry,
    the cells at which the worst branch's WSS error reaches that level
    (cells_for_worst; None where not reached), and how each figure was
    found ("interpolated", "below": already at the coarsest mesh, "above":
    not reached at the finest)."""
    out = {}
    for percent in (1, 2):
        cells, how = {}, {}
        for name, g in sorted(data["geometries"].items()):
            for key, (value, h) in cells_for_worst(g["runs"], percent / 100).items():
                cells.setdefault(key, {})[name] = value
                how.setdefault(key, {})[name] = h
        out["cells_for_worst_%dpct" % percent] = cells
        out["cells_for_worst_%dpct_how" % percent] = how
    return out


def summary_table(results):
    """The Markdown table: one row per mesh, its WSS error range over the
    branches, the cells across the widest and narrowest ones and the
    times."""
    ds = [s["diameter_mm"] for r in done(results)[:1] for s in r["segments"]]
    rows = ["| mesher | parameter | cells | WSS error, min to max | spread (points) | worst dp/dz error | "
            "cells across, %.3g / %.3g mm | mesh (s) | simpleFoam (s) | iterations | checkMesh |" % (max(ds), min(ds)),
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in done(results):
        errors = [s["wss_error"] for s in r["segments"]]
        rows.append("| %s | %s %g | %d | %+.2f%% to %+.2f%% | %.2f | %.2f%% | %.1f / %.1f | %.1f | %.1f | %d%s | %s |"
                    % (MESHERS[r["mesher"]][0], MESHERS[r["mesher"]][2], r["parameter"], r["cells"],
                       100 * min(errors), 100 * max(errors), 100 * spread(r), 100 * worst(r, "dpdz_error"),
                       *across_range(r),
                       r["mesh_seconds"], r["solver_seconds"], r["iterations"],
                       "" if r["converged"] else " (not converged)", "OK" if r["mesh_ok"] else "failed"))
    return "\n".join(rows)


def across_table(results):
    """The Markdown table of the cells across each diameter: one row per
    mesh, one column per diameter (the mean over the branches of that
    diameter)."""
    ok = done(results)
    ds = sorted({round(s["diameter_mm"], 6) for r in ok for s in r["segments"]}, reverse=True)
    rows = ["| mesher | parameter | cells | %s |" % " | ".join("%.3g mm" % d for d in ds),
            "|---|---|---|%s" % ("---|" * len(ds))]
    for r in ok:
        cols = []
        for d in ds:
            n = [s["cells_across"] for s in r["segments"] if abs(s["diameter_mm"] - d) < 1e-6 * d]
            cols.append("%.1f" % (sum(n) / len(n)))
        rows.append("| %s | %s %g | %d | %s |" % (MESHERS[r["mesher"]][0], MESHERS[r["mesher"]][2], r["parameter"],
                                                r["cells"], " | ".join(cols)))
    return "\n".join(rows)


def describe_cells(value, how):
    """A summary figure in words."""
    if value is None:
        return "not reached"
    return ("at most %d (its coarsest mesh)" % value) if how == "below" else "about %d" % value


def compare(mine, theirs, what):
    """`mine` against `theirs` (smaller is better) in words: "about the
    same as" below a ratio of AS_GOOD, else how many times smaller or
    larger."""
    if max(mine, theirs) <= 0:
        return "the same as"
    ratio = max(mine, theirs) / max(min(mine, theirs), 1e-12)
    if ratio < AS_GOOD:
        return "about the same as"
    return "%.1f times %s than" % (ratio, "smaller" if mine < theirs else "larger") + (" " + what if what else "")


def claim(results, piece, pieces):
    """The claim paragraphs, computed: each mesh's spread of the WSS error
    over the pieces (`piece`, plural `pieces`: segment or branch),
    scalemesh's at each M against every peer's, the worst WSS, dp/dz and
    cross-section errors, the cells each mesher needs for a worst branch
    within 1% and 2%, and the outlets' shares of the flow rate when there
    are several."""
    results = done(results)
    own = [r for r in results if r["mesher"].startswith("scalemesh")]
    peers = [r for r in results if not r["mesher"].startswith("scalemesh")]

    def label(r):
        return "%s at %s = %g" % (MESHERS[r["mesher"]][0], MESHERS[r["mesher"]][2], r["parameter"])

    def name(r):
        return "%s (%d cells)" % (label(r), r["cells"])
    lines = ["Spread of the mean wall shear stress error over the %d %s (max - min, percentage points): %s."
             % (len(results[0]["segments"]), pieces, "; ".join("%s %.2f" % (name(r), 100 * spread(r))
                                                               for r in results))]
    for r in own:
        if peers:
            lines.append("%s: spread %.2f points, %s." % (name(r), 100 * spread(r), "; ".join(
                "%s that of %s (%d cells, %.2f points)" % (compare(spread(r), spread(p), ""), label(p), p["cells"],
                                                           100 * spread(p)) for p in peers)))
    lines.append("Largest |WSS error| in any %s: %s." % (piece, "; ".join(
        "%s %.2f%% (%.2f%% against its own cross-section)" % (name(r), 100 * worst(r), 100 * worst(r, "wss_error_own"))
        for r in results)))
    lines.append("Largest |pressure gradient error| in any %s: %s." % (piece, "; ".join(
        "%s %.2f%%" % (name(r), 100 * worst(r, "dpdz_error")) for r in results)))
    lines.append("The mesh's cross-section against the circle's, over the %s: %s." % (pieces, "; ".join(
        "%s %+.2f%% to %+.2f%%" % (name(r), 100 * min(s["cross_section_error"] for s in r["segments"]),
                                   100 * max(s["cross_section_error"] for s in r["segments"])) for r in results)))
    if own:
        lines.append("Cells across a diameter (each layer or cell counted once), lowest to highest over the %s: %s."
                     % (pieces, "; ".join(
                         "%s %.1f to %.1f (%s M +- 1)" % (
                             name(r), min(s["cells_across"] for s in r["segments"]),
                             max(s["cells_across"] for s in r["segments"]),
                             "within" if all(abs(s["cells_across"] - r["parameter"]) <= 1 for s in r["segments"])
                             else "not all within") for r in own)
                         + "; the peers: " + "; ".join(
                         "%s %.1f to %.1f" % (name(r), min(s["cells_across"] for s in r["segments"]),
                                             max(s["cells_across"] for s in r["segments"])) for r in peers)))
    for percent in (1, 2):
        found = cells_for_worst(results, percent / 100)
        lines.append("Cells for a worst %s within %d%% (WSS; where a mesher's error falls to it and stays below in "
                     "its finer meshes, log-log interpolated, failed runs left out): %s." % (piece, percent, "; ".join(
            "%s %s" % (key, describe_cells(value, how)) for key, (value, how) in found.items())))
    shares = [f for r in results for f in r["outlet_flow_fractions"].values()]
    if len(results[0]["outlet_flow_fractions"]) > 1:
        lines.append("Flow rate through each outlet as a share of the inlet's: %.4f to %.4f over the %d outlets and "
                     "the meshes (equal shares: %.4f); each branch's reference is at the sum of its outlets' "
                     "measured shares." % (min(shares), max(shares), len(results[0]["outlet_flow_fractions"]),
                                           1 / len(results[0]["outlet_flow_fractions"])))
    unconverged = [name(r) for r in results if not r["converged"]]
    if unconverged:
        lines.append("Not converged (stopped at the iteration limit): %s." % ", ".join(unconverged))
    return "\n\n".join(lines)


def doc_markers(geometry):
    """The markers around the geometry's section of the page."""
    return ("<!-- multiscale_validation.py %s: begin (generated, do not edit) -->" % geometry,
            "<!-- multiscale_validation.py %s: end -->" % geometry)


def doc_section(g, plot_path=None):
    """The page section (markers included) of one geometry's entry `g` of
    a results file; `plot_path`, relative to the page, the plot to show."""
    geometry = GEOMETRIES[g["geometry"]]
    begin, end = doc_markers(geometry.name)
    results = g["runs"]
    ok = done(results)
    if not ok:
        raise RuntimeError("no run of the %s succeeded" % geometry.name)
    peers = sorted({r["mesher"] for r in results} - {"scalemesh"}, key=list(MESHERS).index)
    ds = [s["diameter_mm"] for s in ok[0]["segments"]]
    reynolds = [s["reynolds"] for r in ok for s in r["segments"]]
    intro = (
        "Generated by `validation/multiscale_validation.py`; do not edit by hand. {description}. Built exactly by "
        "Gmsh's OpenCASCADE kernel and written as an STL of {triangles} triangles ({around} around each "
        "circumference) that every surface-based mesher gets; Gmsh meshes the exact geometry. Laminar flow "
        "(simpleFoam with the settings scalemesh writes, nu = {nu:g} m^2/s, uniform inflow {u:g} m/s over the "
        "{d0:.3g} mm inlet, Reynolds number {re_min:.2g} to {re_max:.2g}); the middle half of each {piece}'s "
        "straight length compared with Hagen-Poiseuille at its share of the mesh's flow rate: the mean wall "
        "shear stress (WSS) error against the exact circle and against a circle of the mesh's own "
        "cross-section there (which leaves out the area the facets and the mesh's wall take), its local RMS, "
        "the pressure gradient error, the cells across a diameter (each cell's chord over its own extent along "
        "the line, so one layer counts 1 whatever its cells; averaged over 4 lines), the cells a diameter line "
        "passes through and the mesh's cross-section. A mesher that resolves every cross-section alike has the "
        "same errors in every {piece}, from {d0:.3g} mm down to {d1:.3g} mm."
    ).format(description=geometry.description(), triangles=g["stl_triangles"], around=g["curvature_elements"],
             nu=g["nu"], u=g["inlet_speed"], d0=max(ds), d1=min(ds), re_min=min(reynolds), re_max=max(reynolds),
             piece=geometry.piece)
    if {"mesh3", "mesh3-radius", "netgen-curvature"} & set(peers):
        intro += (" CGAL Mesh_3 and Netgen get the same triangulation ending at the openings (the others' STL "
                  "runs on past them).")
    legend = "\n".join(["| mesher | parameter | meaning |", "|---|---|---|"]
                       + ["| %s | %s | %s |" % (MESHERS[m][0], MESHERS[m][2], MESHERS[m][1])
                          for m in MESHERS if any(r["mesher"] == m for r in results)])
    commands = list(dict.fromkeys(r["command"] for r in results))
    run_note = ("Run on {dates} on {cores} cores ({cpu}, load average {load:.1f} to {load_max:.1f} as each "
                "command started, other jobs included), the source tree at {commits}. The script's docstring explains the peers' "
                "settings.").format(
        dates=" to ".join(dict.fromkeys([min(r["date"][:10] for r in results), max(r["date"][:10] for r in results)])),
        cores=results[0]["cores"], cpu=results[0]["cpu"], load=min(r["load_average"] for r in results),
        load_max=max(r["load_average"] for r in results),
        commits=", ".join(sorted({r["commit"] for r in results})))

    def fill(text):
        return textwrap.fill(text, 76, break_on_hyphens=False, break_long_words=False)
    parts = ([begin, "# CFD validation: " + geometry.title, fill(intro)]
             + [fill(line) for line in claim(results, geometry.piece, geometry.pieces).split("\n\n")]
             + (["![Worst %s's WSS error against cells, per mesher](%s)" % (geometry.piece, plot_path)]
                if plot_path else [])
             + [legend, summary_table(results), "Cells across each diameter:", across_table(results),
                table(results), "## Rerun",
                "```sh\n%s\n```" % "\n".join(commands), fill(run_note), end])
    return "\n\n".join(parts)


def plot(data, png, workdir):
    """The log-log plot of the worst branch's |WSS error| against cells,
    one panel per geometry of `data`, one line per mesher (gnuplot);
    False without gnuplot."""
    if not have_gnuplot():
        return False
    os.makedirs(workdir, exist_ok=True)
    panels = []
    for name, g in sorted(data["geometries"].items()):
        curves = []
        for i, mesher in enumerate(MESHERS):
            runs = sorted((r for r in done(g["runs"]) if r["mesher"] == mesher), key=lambda r: r["cells"])
            if not runs:
                continue
            path = write_series(os.path.join(workdir, "plot-%s-%s.dat" % (name, mesher)),
                                ((r["cells"], max(100 * worst(r), 1e-3)) for r in runs))
            curves.append("'%s' u 1:2 w lp pt %d lc %d lw 2 t \"%s\"" % (path, 4 + 2 * i, i + 1,
                                                                         MESHERS[mesher][0]))
        panels.append('set title "%s"\nplot %s, 1 w l dt 2 lc "black" t "1%%", 2 w l dt 3 lc "black" t "2%%"'
                      % (GEOMETRIES[name].title, ", ".join(curves)))
    script = """
set terminal pngcairo size {width},620 font ",11" noenhanced
set output '{png}'
set multiplot layout 1,{n} title "Worst segment or branch: |mean wall shear stress error| against Hagen-Poiseuille"
set logscale xy
set grid
set xlabel "cells"
set ylabel "worst |WSS error| (%)"
set key below maxrows 4
{panels}
unset multiplot
""".format(width=760 * len(panels), png=png, n=len(panels), panels="\n".join(panels))
    return run_gnuplot(script, os.path.join(workdir, "plot.gp"))


# ---------------------------------------------------------------- results file

def load_results(path):
    """The results file at `path`, or an empty one."""
    if path and os.path.exists(path):
        with open(path) as f:
            data = json.load(f)
        if "geometries" not in data:
            raise RuntimeError("%s is not a %s (no \"geometries\")" % (path, RESULTS_NAME))
        return data
    return {"geometries": {}, "summary": {}}


def add_run(data, surface, run, drop_other_surface=True):
    """Puts `run` into the geometry entry of `data` whose surface is
    `surface` (geometry, triangles, flow settings), replacing a run of the
    same mesher and parameter; an entry of another surface is dropped (or,
    without drop_other_surface, refused)."""
    g = data["geometries"].get(surface["geometry"])
    if g is None or any(g.get(k) != v for k, v in surface.items()):
        if g is not None and not drop_other_surface:
            raise SystemExit("%s: the runs to merge are on another surface or flow than those there (%s); nothing "
                             "merged" % (surface["geometry"], ", ".join(k for k, v in surface.items() if g.get(k) != v)))
        if g is not None:
            log("%s: its runs were on another surface or flow; dropped" % surface["geometry"])
        g = data["geometries"][surface["geometry"]] = dict(surface, runs=[])
    g["runs"] = [r for r in g["runs"] if (r["mesher"], r["parameter"]) != (run["mesher"], run["parameter"])]
    g["runs"].append(run)
    g["runs"].sort(key=lambda r: (list(MESHERS).index(r["mesher"]), r["parameter"]))


def save_results(path, data):
    """Writes `data` with its summary recomputed to `path` (whole or not
    at all)."""
    data["summary"] = summary(data)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path + ".tmp", "w") as f:
        json.dump(data, f, indent=1)
    os.replace(path + ".tmp", path)


def against_committed(data, committed):
    """Lines comparing the scalemesh figures of `data` (cells for a worst
    branch within 1% and 2%) with the peers' in the committed results
    `committed`, against the goal of GOAL times fewer cells."""
    lines = []
    for key in ("cells_for_worst_1pct", "cells_for_worst_2pct"):
        mine, theirs = data["summary"].get(key, {}), committed["summary"].get(key, {})
        for name in sorted(data["geometries"]):
            for own in (k for k in mine if k.startswith("scalemesh")):
                cells = mine[own].get(name)
                parts = []
                for peer, by_geometry in sorted(theirs.items()):
                    if peer.startswith("scalemesh") or name not in by_geometry:
                        continue
                    other = by_geometry[name]
                    if cells is None or other is None:
                        parts.append("%s %s" % (peer, "not reached" if other is None else other))
                    else:
                        parts.append("%s %d (%.2f times scalemesh's%s)" % (peer, other, other / cells,
                                                                          "" if other >= GOAL * cells
                                                                          else ", short of %g" % GOAL))
                lines.append("%s, %s, %s: %s; committed peers: %s" % (name, own, key,
                                                                     "not reached" if cells is None else cells,
                                                                     "; ".join(parts) or "none"))
    return lines


# ---------------------------------------------------------------- main

def run_metadata(start):
    """What a run records of where and when it ran."""
    return {"command": " ".join(["/usr/bin/python3", os.path.relpath(os.path.abspath(__file__), REPO)]
                                + [os.path.relpath(a, REPO) if os.path.isabs(a) and a.startswith(REPO) else a
                                   for a in sys.argv[1:]]),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(start)), "cores": os.cpu_count(),
            "cpu": cpu_model(), "commit": commit(), "load_average": os.getloadavg()[0]}


def commit():
    """The source tree's commit, with uncommitted changes or not."""
    try:
        head = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()
        changed = subprocess.run(["git", "-C", REPO, "status", "--porcelain", "--untracked-files=no"],
                                 capture_output=True, text=True, check=True).stdout.strip()
        return "commit %s%s" % (head, " with uncommitted changes" if changed else "")
    except (OSError, subprocess.CalledProcessError):
        return "an unknown commit"


def quick_failures(results, tolerance, spread_across):
    """What the quick check finds wrong with scalemesh's runs: a failed
    run, checkMesh failing, no convergence, a branch's mean WSS beyond
    `tolerance` of Hagen-Poiseuille, cells across beyond M +- spread_across."""
    own = [r for r in results if r["mesher"].startswith("scalemesh")]
    out = [] if own else ["no scalemesh run"]
    for r in own:
        name = "%s M %g" % (r["mesher"], r["parameter"])
        if "failed" in r:
            out.append("%s failed" % name)
            continue
        if not r["mesh_ok"]:
            out.append("%s: checkMesh failed" % name)
        if not r["converged"]:
            out.append("%s: not converged in %d iterations" % (name, r["iterations"]))
        for s in r["segments"]:
            if abs(s["wss_error"]) > tolerance:
                out.append("%s, %s: WSS error %+.2f%%, beyond %g%%" % (name, s["label"], 100 * s["wss_error"],
                                                                     100 * tolerance))
            if abs(s["cells_across"] - r["parameter"]) > spread_across:
                out.append("%s, %s: %.1f cells across, not within M +- %g" % (name, s["label"], s["cells_across"],
                                                                          spread_across))
            if s["odd_lines"]:
                out.append("%s, %s: %d lines not across 2 walls" % (name, s["label"], s["odd_lines"]))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scalemesh", default=os.path.join(REPO, "build", "src", "cli", "scalemesh"),
                    help="the scalemesh binary (default: %(default)s)")
    ap.add_argument("--out", default=os.path.join(REPO, "build", "multiscale"),
                    help="directory of the results file %s, which each run is merged into (a run replaces one of "
                    "the same mesher and parameter; default: %%(default)s)" % RESULTS_NAME)
    ap.add_argument("--workdir", help="case directories (default: OUT/GEOMETRY)")
    ap.add_argument("--fresh", action="store_true",
                    help="replace OUT's runs of the geometry when they were made on another surface or flow "
                    "(another --elements, --quick); without it such a run is refused before anything runs")
    ap.add_argument("--geometry", choices=sorted(GEOMETRIES),
                    help="the stepped tube or the bifurcating tree (default: stepped; with --from-json, every "
                    "geometry of the file)")
    ap.add_argument("--M", type=float, nargs="+", help="scalemesh layer counts (default: %s; with --quick, %g)"
                    % (" ".join("%g" % m for m in DEFAULT_M), QUICK_M))
    ap.add_argument("--layers", nargs="+", choices=["delaunay", "prisms"], default=["delaunay"],
                    help="scalemesh's wall layers, each at every M: the paper's Delaunay layers, prism layers, or "
                    "both (default: %(default)s)")
    ap.add_argument("--only", nargs="+", choices=["scalemesh"] + [m for m in MESHERS if not m.startswith("scalemesh")],
                    help="run only these meshers (a peer still needs a scalemesh case for its solver settings: one "
                    "is meshed, not solved, when scalemesh is not among them)")
    ap.add_argument("--gmsh-h", type=float, nargs="*", default=[], metavar="H",
                    help="Gmsh peer: isotropic element sizes in mm (default: none)")
    ap.add_argument("--gmsh-curvature", type=float, nargs="*", default=[], metavar="N",
                    help="Gmsh peer sized from curvature: N elements per 2 pi radians (default: none)")
    ap.add_argument("--snappy", type=float, nargs="*", default=[], metavar="N",
                    help="snappyHexMesh peer, stepped tube only: about N cells across every segment (background "
                    "cell %g / N mm, one refinement level per halving of the diameter; default: none)" % DIAMETERS[0])
    ap.add_argument("--mesh3-h", type=float, nargs="*", default=[], metavar="H",
                    help="CGAL Mesh_3 peer: every size bound H mm (default: none)")
    ap.add_argument("--mesh3-radius", type=float, nargs="*", default=[], metavar="F",
                    help="CGAL Mesh_3 peer sized from the centreline: size F times the local radius (default: none)")
    ap.add_argument("--netgen-curvature", type=float, nargs="*", default=[], metavar="F",
                    help="Netgen peer (validation/netgen_peer.py, Debian python3-netgen): sizes from the STL's "
                    "curvature, h <= r / F, 3 prism layers on the wall (default: none)")
    ap.add_argument("--mesh3-surface", default=os.path.join(REPO, "build", "validation", "mesh3_surface"),
                    help="the mesh3_surface binary (default: %(default)s)")
    ap.add_argument("--quick", action="store_true",
                    help="check: an STL of %d triangles around (unless --elements), at most %d SIMPLE iterations, and exit 1 unless "
                    "every scalemesh run passes checkMesh, converges, has every %s's mean WSS within %g%%%% of "
                    "Hagen-Poiseuille and %g of M cells across it"
                    % (QUICK_CURVATURE_ELEMENTS, QUICK_ITERATIONS, "segment or branch", 100 * QUICK_WSS,
                       QUICK_ACROSS))
    ap.add_argument("--elements", type=int, metavar="N",
                    help="STL triangles around each circumference (default: %d; with --quick, %d)"
                    % (CURVATURE_ELEMENTS, QUICK_CURVATURE_ELEMENTS))
    ap.add_argument("--doc", metavar="PATH",
                    help="also write the results sections into this page (e.g. docs/validation.md), between "
                    "the markers %s and %s (one section per geometry), appended if it has none"
                    % doc_markers("GEOMETRY"))
    ap.add_argument("--plot", metavar="PNG",
                    help="also draw the worst branch's error against cells, per mesher and geometry (gnuplot); "
                    "the page shows it when it lies beside --doc")
    ap.add_argument("--from-json", metavar="PATH",
                    help="run nothing: the sections (and --plot) from this results file, into --doc or, without "
                    "it, to stdout")
    ap.add_argument("--merge", nargs="+", metavar="PATH",
                    help="run nothing: merge the runs of these results files into OUT's (a run replaces one of the "
                    "same mesher and parameter), then write --doc and --plot from it")
    ap.add_argument("--committed", default=os.path.join(REPO, "validation", RESULTS_NAME),
                    help="the results to compare scalemesh's cells for a worst branch within 1%% and 2%% with "
                    "(default: %(default)s)")
    args = ap.parse_args()
    # The cases run in their own directories: every path absolute.
    if args.merge:
        args.merge = [os.path.abspath(path) for path in args.merge]
    for name in ("scalemesh", "workdir", "out", "doc", "plot", "mesh3_surface", "from_json", "committed"):
        value = getattr(args, name)
        if value and (name != "scalemesh" or os.sep in value):  # a bare name is looked up on PATH
            setattr(args, name, os.path.abspath(value))
    plot_link = (os.path.relpath(args.plot, os.path.dirname(args.doc))
                 if args.plot and args.doc and os.path.dirname(args.plot) == os.path.dirname(args.doc) else None)

    def write_outputs(data):
        if args.plot:
            with tempfile.TemporaryDirectory() as scratch:  # gnuplot's data files
                plot(data, args.plot, scratch)
        names = [args.geometry] if args.geometry and args.from_json else sorted(data["geometries"])
        for name in names:
            if name not in data["geometries"]:
                raise SystemExit("no %s in the results" % name)
            section = doc_section(data["geometries"][name], plot_link)
            if args.doc:
                replace_section(args.doc, section, *doc_markers(name))
                log("wrote the %s section into %s" % (name, args.doc))
            else:
                print(section)

    if args.from_json:
        write_outputs(load_results(args.from_json))
        return 0
    if args.merge:
        results_path = os.path.join(args.out, RESULTS_NAME)
        os.makedirs(args.out, exist_ok=True)
        with open(results_path + ".lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            data = load_results(results_path)
            for path in args.merge:
                other = load_results(path)
                if not other["geometries"]:
                    raise SystemExit("%s holds no runs" % path)
                for g in other["geometries"].values():
                    surface = {k: v for k, v in g.items() if k != "runs"}
                    for r in g["runs"]:
                        add_run(data, surface, r, drop_other_surface=False)
                log("merged the runs of %s into %s" % (path, results_path))
            save_results(results_path, data)
        if args.doc or args.plot:
            write_outputs(data)
        return 0

    geometry = GEOMETRIES[args.geometry or "stepped"]
    if args.snappy and geometry.name != "stepped":
        ap.error("--snappy: the stepped tube only (its inlet and outlet are the ends of snappy's block)")
    binary = os.path.abspath(args.scalemesh) if os.sep in args.scalemesh else shutil.which(args.scalemesh)
    if not binary or not os.access(binary, os.X_OK):
        sys.exit("no scalemesh binary at %s (pass --scalemesh)" % args.scalemesh)
    only = set(args.only or ["scalemesh"] + list(MESHERS))
    peer_params = [(m, p) for m, ps in (("gmsh", args.gmsh_h), ("gmsh-curvature", args.gmsh_curvature),
                                        ("snappy", args.snappy), ("mesh3", args.mesh3_h),
                                        ("mesh3-radius", args.mesh3_radius),
                                        ("netgen-curvature", args.netgen_curvature)) if m in only for p in ps]
    if {"mesh3", "mesh3-radius"} & {m for m, _ in peer_params} and not os.access(args.mesh3_surface, os.X_OK):
        sys.exit("no mesh3_surface binary at %s: build it with `cmake --build build --target mesh3_surface` "
                 "(it is not in the default target), or pass --mesh3-surface" % args.mesh3_surface)
    Ms = args.M or ([QUICK_M] if args.quick else DEFAULT_M)
    iterations = QUICK_ITERATIONS if args.quick else None
    elements = args.elements or (QUICK_CURVATURE_ELEMENTS if args.quick else CURVATURE_ELEMENTS)
    workdir = args.workdir or os.path.join(args.out, geometry.name)
    os.makedirs(workdir, exist_ok=True)
    os.makedirs(args.out, exist_ok=True)
    results_path = os.path.join(args.out, RESULTS_NAME)
    data = load_results(results_path)   # refused early when it is not a results file
    start = time.time()
    meta = run_metadata(start)

    stl = os.path.join(workdir, STL_NAME)
    triangles = write_surface_stl(geometry, stl, elements)
    surface = {"geometry": geometry.name, "stl_triangles": triangles, "curvature_elements": elements,
               "nu": NU, "inlet_speed": U_IN, "max_iterations": iterations,
               "diameters_mm": sorted({b["diameter"] for b in geometry.branches()}, reverse=True)}
    stl_exact = os.path.join(workdir, "between-openings.stl")
    if {"mesh3", "mesh3-radius", "netgen-curvature"} & {m for m, _ in peer_params}:
        write_surface_stl(geometry, stl_exact, elements, margins=False)
    log("%s: diameters %s mm, %d STL triangles (%d around)"
        % (geometry.title, " / ".join("%.3g" % d for d in surface["diameters_mm"]), triangles, elements))
    held = data["geometries"].get(geometry.name)
    other = [k for k, v in surface.items() if held is not None and held.get(k) != v]
    if other and not args.fresh:
        raise SystemExit("%s holds %s runs made on another surface or flow (%s): they would be dropped. Run "
                         "with --fresh to replace them, or give another --out" % (results_path, geometry.name,
                                                                                   ", ".join(other)))

    results = []

    def record(result):
        nonlocal data
        result.update(meta)
        result["case"] = os.path.relpath(result["case"], args.out)
        results.append(result)
        # Read again under a lock: another run (the other geometry) may
        # have merged its own since.
        with open(results_path + ".lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            data = load_results(results_path)
            add_run(data, surface, result, drop_other_surface=args.fresh)
            save_results(results_path, data)

    template = None
    for layers in args.layers:
        mesher = "scalemesh" if layers == "delaunay" else "scalemesh-prisms"
        for M in Ms:
            case = os.path.join(workdir, "%s-M%g" % (mesher, M))

            def make_mesh(M=M, case=case, layers=layers):
                seconds, report = scalemesh_case(binary, geometry, M, case, stl, layers)
                return seconds, {"max_non_orthogonality_deg": report.get("max_non_orthogonality_deg")}
            if "scalemesh" in only:
                record(study_one(geometry, mesher, M, case, make_mesh, iterations))
                if template is None and "failed" not in results[-1]:
                    template = case
    if peer_params and template is None:
        template = os.path.join(workdir, "template")
        scalemesh_case(binary, geometry, Ms[0], template, stl, args.layers[0])
    makers = {
        "gmsh": lambda h, case: (gmsh_case(geometry, gmsh_uniform(h), case, template), {}),
        "gmsh-curvature": lambda n, case: (gmsh_case(geometry, gmsh_curvature(n), case, template), {}),
        "snappy": lambda n, case: snappy_case(n, case, template, stl),
        "mesh3": lambda h, case: (mesh3_case(geometry, args.mesh3_surface, mesh3_sizes(geometry, "mesh3", h), case,
                                             template, stl_exact), {}),
        "mesh3-radius": lambda f, case: (mesh3_case(geometry, args.mesh3_surface,
                                                    mesh3_sizes(geometry, "mesh3-radius", f), case, template,
                                                    stl_exact), {}),
        "netgen-curvature": lambda f, case: netgen_case(stl_exact, geometry.openings(), case, template,
                                                        NETGEN_MAXH * geometry.inlet_diameter, curvature=f),
    }
    for mesher, param in peer_params:
        case = os.path.join(workdir, "%s-%s%g" % (mesher, MESHERS[mesher][2], param))
        record(study_one(geometry, mesher, param, case, lambda m=makers[mesher], p=param, c=case: m(p, c),
                         iterations))

    ok = done(results)
    if ok:
        log("\n%s\n\n%s\n\n%s\n" % (table(results), summary_table(results),
                                    claim(results, geometry.piece, geometry.pieces)))
    if os.path.exists(args.committed) and os.path.abspath(args.committed) != results_path:
        for line in against_committed(data, load_results(args.committed)):
            log(line)
    if args.doc or args.plot:
        write_outputs(data)
    log("wrote %s in %.0f s" % (results_path, time.time() - start))
    if args.quick:
        wrong = quick_failures(results, QUICK_WSS, QUICK_ACROSS)
        for line in wrong:
            log("quick check: " + line)
        if wrong:
            return 1
        log("quick check passed: %d scalemesh runs" % sum(r["mesher"].startswith("scalemesh") for r in results))
    return 0 if len(ok) == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())
