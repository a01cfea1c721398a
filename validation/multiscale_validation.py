#!/usr/bin/python3
"""Multi-scale flow benchmark: a stepped tube in series or a bifurcating
tree, scalemesh and its peers.

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

--geometry tree: a symmetric planar bifurcating tree instead (Tree: 4
generations, the root 6 mm, each daughter 0.6 of its parent down to
1.3 mm, branches 7 diameters long, daughters at +-30 degrees, cylinders and
a sphere of the parent's diameter at each junction fused by OCC), the inlet
at the root and an [[openings]] plane at each of the 8 leaf ends (outlet_L..,
outlet_R.., the path from the root; each with a radius picking its own
crossing). Every branch of generation g carries Q / 2^g by symmetry (the
outlets all at p = 0, the flow nearly Stokes), so each branch's middle half
has the Hagen-Poiseuille values at that share; the flux through each
outlet is measured too, to show how far a mesh breaks the symmetry.

    /usr/bin/python3 validation/multiscale_validation.py            # M = 5 7 10
    /usr/bin/python3 validation/multiscale_validation.py --quick    # M = 5 only,
        # at most 500 SIMPLE iterations: a smoke test
    /usr/bin/python3 validation/multiscale_validation.py --M 7 --gmsh-h 0.8 0.5
        # also Gmsh peers: isotropic tets of 0.8 and 0.5 mm (40k, 160k cells)
        # on the same geometry
    /usr/bin/python3 validation/multiscale_validation.py --gmsh-curvature 20 \
        --snappy 8 --doc docs/validation.md    # the scale-aware peers (about
        # 40k and 50k cells), the results section written into the page
    /usr/bin/python3 validation/multiscale_validation.py \
        --from-json build/multiscale/results.json --doc docs/validation.md
        # the section again from a run's JSON, nothing run
    /usr/bin/python3 validation/multiscale_validation.py --geometry tree \
        --M 5 10 --gmsh-h 0.5 --gmsh-curvature 16    # the tree
    /usr/bin/python3 validation/multiscale_validation.py --M 7 \
        --mesh3-h 0.8 --mesh3-radius 0.4 0.3    # the CGAL Mesh_3 peers (41k;
        # 23k and 48k cells), after cmake --build build --target mesh3_surface

It prints Markdown tables (one row per mesh and segment or branch; one per
mesh with the spread of the WSS error over them) and the claim paragraph,
and writes the results to --out (JSON). Runs go into --workdir (one case
directory per mesh, the STL in its root). --doc PATH puts the section
between the geometry's markers (doc_markers) in the page, appended at its
end when it has none; --from-json regenerates it from a results JSON.
tube_validation.py rewrites the rest of the page through
common.write_page, which keeps these sections as they are.

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
        are about 1.6 F r, some 1.2 / F edges along a diameter; a diameter
        line crosses more tets than that (F = 0.4 and 0.3: about 16 and 21
        cells across; 23k and 48k cells on the stepped tube, 62k and 129k
        on the tree). Isotropic, no wall layers.

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
centres' pressures there, the cells across a diameter (the cells a line
through the axis in the middle cross-section passes through, i.e. the
interior faces it crosses plus one, averaged over 4 directions 45 degrees
apart) and the mesh's cross-section (cell volume / length) against pi R^2;
per mesh, the share of the inlet's flow rate through each outlet.
"""

import argparse
import json
import math
import os
import re
import shutil
import subprocess
import sys
import textwrap
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (REPO, log, run, solve, latest_time, internal_field,  # noqa: E402
                    patch_field, boundary_faces, foam_list_lines, replace_section, snappy_tube)
from tube_validation import case_from_template, foam_from_msh  # noqa: E402

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
CURVATURE_ELEMENTS = 24            # surface triangles around a circumference

DEFAULT_M = [5, 7, 10]
# The meshers: a name for the page, what their parameter is, its symbol
# (also the case directory's prefix before its value).
MESHERS = {
    "scalemesh": ("scalemesh", "layers across every cross-section", "M"),
    "gmsh": ("Gmsh, uniform", "element size everywhere (mm)", "h"),
    "gmsh-curvature": ("Gmsh, sized from curvature", "elements per 2 pi radians of curvature", "N"),
    "snappy": ("snappyHexMesh, a level per segment", "cells across every segment", "N"),
    "mesh3": ("CGAL Mesh_3, uniform", "size bound everywhere (mm): edges, surface balls, tet circumradii", "h"),
    "mesh3-radius": ("CGAL Mesh_3, sized from the radius",
                     "size bound as a fraction of the local radius, from the centreline", "F"),
}
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
            out.append({"label": "segment %d" % (len(out) + 1), "diameter": d, "a": (0, 0, z0 + quarter),
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
            out.append({"label": "g%d %s" % (b["generation"], b["label"] or "root"), "diameter": b["diameter"],
                        "a": along(b["start"], b["direction"], quarter), "b": along(b["end"], b["direction"], -quarter),
                        "flow_fraction": 0.5 ** b["generation"]})
        return out


GEOMETRIES = {g.name: g for g in (SteppedTube(), Tree())}


def write_surface_stl(geometry, path, margins=True):
    """The exact geometry (with `margins`, running on past the openings) as
    an ASCII STL, CURVATURE_ELEMENTS triangles around each circumference;
    returns its triangle count."""
    import gmsh  # Debian python3-gmsh

    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(geometry.name)
        geometry.build(gmsh, margins)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", CURVATURE_ELEMENTS)
        gmsh.option.setNumber("Mesh.MeshSizeMax", 2.0)   # flat discs and long wide cylinders
        gmsh.option.setNumber("Mesh.Binary", 0)
        gmsh.model.mesh.generate(2)
        gmsh.write(path)
        _, tags, _ = gmsh.model.mesh.getElements(2)
        return sum(len(t) for t in tags)
    finally:
        gmsh.finalize()


# ---------------------------------------------------------------- meshes

def case_file(geometry, M):
    """The scalemesh.toml text for the geometry's STL at layer count M."""
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

[output]
surface = []
%s
[flow]
viscosity = %g
inlet_speed = %g
""" % (geometry.title, STL_NAME, M, openings, NU, U_IN)


def fresh_case(case):
    """An empty directory `case` (what was there removed)."""
    if os.path.exists(case):
        shutil.rmtree(case)
    os.makedirs(case)


def scalemesh_case(binary, geometry, M, case, stl):
    """A scalemesh run of the geometry's STL at layer count M into `case`;
    returns (seconds, report.json's openfoam section)."""
    fresh_case(case)
    shutil.copy(stl, os.path.join(case, STL_NAME))
    with open(os.path.join(case, "scalemesh.toml"), "w") as f:
        f.write(case_file(geometry, M))
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
    import gmsh  # Debian python3-gmsh

    case_from_template(case, template)
    t = time.time()
    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(geometry.name)
        vol = geometry.build(gmsh, False)
        # An opening's disc is the surface whose bounding box is centred on
        # the opening's point; the rest is wall.
        names = ["wall"] + [o[0] for o in geometry.openings()]
        groups = {name: [] for name in names}
        for dim, tag in gmsh.model.getEntities(2):
            box = gmsh.model.getBoundingBox(dim, tag)
            centre = [(box[k] + box[k + 3]) / 2 for k in range(3)]
            name = "wall"
            for opening, _, point, _, _ in geometry.openings():
                if math.dist(centre, point) < 1e-3:
                    name = opening
            groups[name].append(tag)
        for i, name in enumerate(names):
            if len(groups[name]) != 1 and name != "wall":
                raise RuntimeError("opening %s is %d surfaces of the Gmsh model" % (name, len(groups[name])))
            gmsh.model.setPhysicalName(2, gmsh.model.addPhysicalGroup(2, groups[name], i + 1), name)
        gmsh.model.setPhysicalName(3, gmsh.model.addPhysicalGroup(3, [vol], len(names) + 1), "fluid")
        for name, value in options.items():
            gmsh.option.setNumber(name, value)
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


def cells_across(points, faces, n_internal, sections):
    """For each cross-section (centre, frame axes, radius): the cells that
    diameter lines through it pass through (the interior faces a line
    crosses plus one), averaged over LINE_ANGLES, and the boundary faces
    crossed per line (2 for a line across a tube). The lines run in the
    section's plane from -1.5 to 1.5 radii, LINE_OFFSET radii beside the
    axis."""
    out = []
    for centre, axes, radius in sections:
        height = [local(p, centre, axes[2:])[0] for p in points]
        cut = [[local(points[i], centre, axes) for i in face] + [k < n_internal]
               for k, face in enumerate(faces)
               if min(height[i] for i in face) <= 0 <= max(height[i] for i in face)]
        inner = outer = 0
        for angle in LINE_ANGLES:
            cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
            for face in cut:
                # The face turned by -angle about the axis: the line runs along x.
                ps = [(p[0] * cos + p[1] * sin, p[1] * cos - p[0] * sin, p[2]) for p in face[:-1]]
                if crosses(ps, LINE_OFFSET * radius, 0.0, 1.5 * radius):
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


def analyse(geometry, case):
    """Per branch (segment) of the geometry: wall shear stress, pressure
    gradient, cross-section and cells across against Hagen-Poiseuille at its
    share of the mesh's flow rate, over the middle half of its straight
    length (the wall faces and cells whose centres project onto it and lie
    within 1.5 radii of its axis)."""
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
    for b in geometry.branches():
        a, e = [v * 1e-3 for v in b["a"]], [v * 1e-3 for v in b["b"]]
        pieces.append((b, a, e, frame(a, e), math.dist(a, e), b["diameter"] * 0.5e-3))
    points, faces, n_internal = mesh_faces(case)
    across = cells_across(points, faces, n_internal, [([(ai + ei) / 2 for ai, ei in zip(a, e)], axes, R)
                                                      for _, a, e, axes, _, R in pieces])

    out = []
    for (b, a, _, axes, length, R), (n_across, n_boundary) in zip(pieces, across):
        def inside(c):
            """The position of c along the axis, or None when c is not in the piece."""
            x, y, s = local(c, a, axes)
            return s if 0 <= s <= length and x * x + y * y <= (1.5 * R) ** 2 else None
        q = Q * b["flow_fraction"]
        tau_ref = 4 * NU * q / (math.pi * R ** 3)
        grad_ref = -8 * NU * q / (math.pi * R ** 4)
        sa = st = sq = 0.0
        for (c, area), t in zip(wall, wss):
            if inside(c) is not None:
                mag_a = math.sqrt(sum(x * x for x in area))
                mag_t = math.sqrt(sum(x * x for x in t))
                sa += mag_a
                st += mag_t * mag_a
                sq += (mag_t - tau_ref) ** 2 * mag_a
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
        out.append({
            "label": b["label"], "diameter_mm": 2e3 * R, "from_mm": list(b["a"]), "to_mm": list(b["b"]),
            "flow_fraction": b["flow_fraction"], "cells": int(n),
            "cells_across": n_across, "boundary_crossings": n_boundary,
            "cross_section_error": sw / length / (math.pi * R ** 2) - 1,
            "tau_w": st / sa, "tau_w_ref": tau_ref, "wss_error": st / sa / tau_ref - 1,
            "wss_rms_error": math.sqrt(sq / sa) / tau_ref,
            "dpdz": slope, "dpdz_ref": grad_ref, "dpdz_error": slope / grad_ref - 1,
            "reynolds": 4 * q / (math.pi * NU * 2 * R),
        })
    return {"cells": len(p), "flow_rate_m3s": Q, "inlet_area_mm2": inlet_area * 1e6, "outlet_flow_fractions": shares,
            "segments": out}


def study_one(geometry, mesher, param, case, make_mesh, iterations):
    """Meshes (make_mesh() returns its seconds and extra fields), solves and
    analyses one case of the geometry; logs a line per branch (segment)."""
    mesh_seconds, extra = make_mesh()
    if iterations:
        limit_iterations(case, iterations)
    result = {"mesher": mesher, "parameter": param, "case": case, "mesh_seconds": mesh_seconds}
    result.update(extra)
    result.update(solve(case))
    result.update(analyse(geometry, case))
    log("%s %g: %d cells, %s after %d iterations, checkMesh %s"
        % (mesher, param, result["cells"], "converged" if result["converged"] else "NOT converged",
           result["iterations"], "OK" if result["mesh_ok"] else "FAILED"))
    for s in result["segments"]:
        log("  %s (D %.3g mm): WSS %+.2f%% (rms %.2f%%), dp/dz %+.2f%%, %.1f cells across, cross-section %+.2f%%"
            % (s["label"], s["diameter_mm"], 100 * s["wss_error"], 100 * s["wss_rms_error"], 100 * s["dpdz_error"],
               s["cells_across"], 100 * s["cross_section_error"]))
    return result


# ---------------------------------------------------------------- report

def table(results):
    """The Markdown table: one row per mesh and branch (segment)."""
    rows = ["| mesher | parameter | cells | segment / branch | D (mm) | its cells | WSS error | WSS RMS | "
            "dp/dz error | cells across | cross-section error |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        for s in r["segments"]:
            rows.append("| %s | %s %g | %d | %s | %.3g | %d | %+.2f%% | %.2f%% | %+.2f%% | %.1f | %+.2f%% |"
                        % (r["mesher"], MESHERS[r["mesher"]][2], r["parameter"], r["cells"], s["label"],
                           s["diameter_mm"], s["cells"], 100 * s["wss_error"], 100 * s["wss_rms_error"],
                           100 * s["dpdz_error"],
                           s["cells_across"], 100 * s["cross_section_error"]))
    return "\n".join(rows)


def wss_spread(result):
    """max - min of the mean WSS error over the branches, as a fraction."""
    errors = [s["wss_error"] for s in result["segments"]]
    return max(errors) - min(errors)


def across_range(result):
    """The mean cells across the widest and across the narrowest branches."""
    out = []
    for pick in (max, min):
        d = pick(s["diameter_mm"] for s in result["segments"])
        n = [s["cells_across"] for s in result["segments"] if abs(s["diameter_mm"] - d) < 1e-6 * d]
        out.append(sum(n) / len(n))
    return out


def summary_table(results):
    """The Markdown table: one row per mesh, its WSS error range over the
    branches, the cells across the widest and narrowest ones and the
    times."""
    ds = [s["diameter_mm"] for s in results[0]["segments"]]
    rows = ["| mesher | parameter | cells | WSS error, min to max | spread (points) | cells across, %.3g / %.3g mm | "
            "mesh (s) | simpleFoam (s) | iterations | checkMesh |" % (max(ds), min(ds)),
            "|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        errors = [s["wss_error"] for s in r["segments"]]
        rows.append("| %s | %s %g | %d | %+.2f%% to %+.2f%% | %.2f | %.1f / %.1f | %.1f | %.1f | %d%s | %s |"
                    % (MESHERS[r["mesher"]][0], MESHERS[r["mesher"]][2], r["parameter"], r["cells"],
                       100 * min(errors), 100 * max(errors), 100 * wss_spread(r),
                       *across_range(r),
                       r["mesh_seconds"], r["solver_seconds"], r["iterations"],
                       "" if r["converged"] else " (not converged)", "OK" if r["mesh_ok"] else "failed"))
    return "\n".join(rows)


def claim(results, piece, pieces):
    """The claim paragraph, computed: each mesh's spread of the WSS error
    over the pieces (`piece`, plural `pieces`: segment or branch),
    scalemesh's at each M against every peer's, and the outlets' shares of
    the flow rate when there are several."""
    own = [r for r in results if r["mesher"] == "scalemesh"]
    peers = [r for r in results if r["mesher"] != "scalemesh"]

    def label(r):
        return "%s at %s = %g" % (MESHERS[r["mesher"]][0], MESHERS[r["mesher"]][2], r["parameter"])

    def name(r):
        return "%s (%d cells)" % (label(r), r["cells"])
    lines = ["Spread of the mean wall shear stress error over the %d %s (max - min, percentage points): %s."
             % (len(results[0]["segments"]), pieces, "; ".join("%s %.2f" % (name(r), 100 * wss_spread(r))
                                                               for r in results))]
    for r in own:
        if not peers:
            break
        wider = [p for p in peers if wss_spread(p) > wss_spread(r)]
        narrower = [p for p in peers if wss_spread(p) <= wss_spread(r)]
        parts = []
        if wider:
            parts.append("smaller than that of %s" % "; ".join(
                "%s (%d cells, %.2f points, %.2f times as much)"
                % (label(p), p["cells"], 100 * wss_spread(p), wss_spread(p) / wss_spread(r)) for p in wider))
        if narrower:
            parts.append("not smaller than that of %s" % "; ".join(
                "%s (%d cells, %.2f points)" % (label(p), p["cells"], 100 * wss_spread(p)) for p in narrower))
        lines.append("scalemesh at M = %g (%d cells): spread %.2f points, %s."
                     % (r["parameter"], r["cells"], 100 * wss_spread(r), "; ".join(parts)))

    def worst(r):
        return max(abs(s["wss_error"]) for s in r["segments"])
    lines.append("Largest |WSS error| in any %s: %s."
                 % (piece, "; ".join("%s %.2f%%" % (name(r), 100 * worst(r)) for r in results)))
    shares = [f for r in results for f in r["outlet_flow_fractions"].values()]
    if len(results[0]["outlet_flow_fractions"]) > 1:
        lines.append("Flow rate through each outlet as a share of the inlet's: %.4f to %.4f over the %d outlets and "
                     "the meshes (equal shares: %.4f)." % (min(shares), max(shares),
                                                            len(results[0]["outlet_flow_fractions"]),
                                                            1 / len(results[0]["outlet_flow_fractions"])))
    unconverged = [name(r) for r in results if not r["converged"]]
    if unconverged:
        lines.append("Not converged (stopped at the iteration limit): %s." % ", ".join(unconverged))
    return "\n\n".join(lines)


def doc_markers(geometry):
    """The markers around the geometry's section of the page."""
    return ("<!-- multiscale_validation.py %s: begin (generated, do not edit) -->" % geometry,
            "<!-- multiscale_validation.py %s: end -->" % geometry)


def doc_section(data):
    """The page section (markers included) from a results JSON's data."""
    geometry = GEOMETRIES[data["geometry"]]
    begin, end = doc_markers(geometry.name)
    results = data["results"]
    peers = sorted({r["mesher"] for r in results} - {"scalemesh"}, key=list(MESHERS).index)
    ds = [s["diameter_mm"] for s in results[0]["segments"]]
    reynolds = [s["reynolds"] for r in results for s in r["segments"]]
    intro = (
        "Generated by `validation/multiscale_validation.py`; do not edit by hand. {description}. Built exactly by "
        "Gmsh's OpenCASCADE kernel and written as an STL of {triangles} triangles that every surface-based mesher "
        "gets; Gmsh meshes the exact geometry. Laminar flow (simpleFoam with the settings scalemesh writes, "
        "nu = {nu:g} m^2/s, uniform inflow {u:g} m/s over the {d0:.3g} mm inlet, Reynolds number {re_min:.2g} to "
        "{re_max:.2g}); the middle half of each {piece}'s straight length compared with Hagen-Poiseuille at its "
        "share of the mesh's flow rate: the mean wall shear stress (WSS) error, its local RMS, the pressure "
        "gradient error, the cells a diameter line crosses and the mesh's cross-section. A mesher that resolves "
        "every cross-section alike has the same errors in every {piece}, from {d0:.3g} mm down to {d1:.3g} mm."
    ).format(description=geometry.description(), triangles=data["stl_triangles"], nu=data["nu"],
             u=data["inlet_speed"], d0=max(ds), d1=min(ds), re_min=min(reynolds), re_max=max(reynolds),
             piece=geometry.piece)
    if {"mesh3", "mesh3-radius"} & set(peers):
        intro += (" CGAL Mesh_3 gets the same triangulation ending at the openings (the others' STL runs on past "
                  "them).")
    legend = "\n".join(["| mesher | parameter | meaning |", "|---|---|---|"]
                       + ["| %s | %s | %s |" % (MESHERS[m][0], MESHERS[m][2], MESHERS[m][1])
                          for m in ["scalemesh"] + peers])
    run_note = ("Run on {date} on {cores} cores ({cpu}, load average {load_start:.1f} at the start, other jobs "
                "included), the source tree at {commit}; {minutes:.1f} minutes wall clock in all. The script's "
                "docstring explains the peers' settings.").format(
        date=data["date"], cores=data["cores"], cpu=data["cpu"], load_start=data["load_average"],
        commit=data["commit"], minutes=data["seconds"] / 60)
    def fill(text):
        return textwrap.fill(text, 76, break_on_hyphens=False, break_long_words=False)
    parts = ([begin, "# CFD validation: " + geometry.title, fill(intro)]
             + [fill(line) for line in claim(results, geometry.piece, geometry.pieces).split("\n\n")]
             + [legend, summary_table(results), table(results), "## Rerun", "```sh\n%s\n```" % data["command"],
                fill(run_note), end])
    return "\n\n".join(parts)


def machine():
    """The CPU model and the source tree's commit (with uncommitted changes
    or not), for the page."""
    cpu = "unknown CPU"
    if os.path.exists("/proc/cpuinfo"):
        m = re.search(r"(?m)^model name\s*:\s*(.+)$", open("/proc/cpuinfo").read())
        cpu = m.group(1).strip() if m else cpu
    try:
        commit = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()
        changed = subprocess.run(["git", "-C", REPO, "status", "--porcelain", "--untracked-files=no"],
                                 capture_output=True, text=True, check=True).stdout.strip()
        commit = "commit %s%s" % (commit, " with uncommitted changes" if changed else "")
    except (OSError, subprocess.CalledProcessError):
        commit = "an unknown commit"
    return cpu, commit


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scalemesh", default=os.path.join(REPO, "build", "src", "cli", "scalemesh"),
                    help="the scalemesh binary (default: %(default)s)")
    ap.add_argument("--workdir", default=os.path.join(REPO, "build", "multiscale"),
                    help="case directories (default: %(default)s)")
    ap.add_argument("--out", default=os.path.join(REPO, "build", "multiscale", "results.json"),
                    help="results JSON (default: %(default)s)")
    ap.add_argument("--geometry", choices=sorted(GEOMETRIES), default="stepped",
                    help="the stepped tube or the bifurcating tree (default: %(default)s)")
    ap.add_argument("--M", type=float, nargs="+", default=DEFAULT_M, help="scalemesh layer counts (default: 5 7 10)")
    ap.add_argument("--gmsh-h", type=float, nargs="*", default=[], metavar="H",
                    help="Gmsh peer: isotropic element sizes in mm (default: none; every peer needs a scalemesh "
                    "case for its solver settings)")
    ap.add_argument("--gmsh-curvature", type=float, nargs="*", default=[], metavar="N",
                    help="Gmsh peer sized from curvature: N elements per 2 pi radians (default: none)")
    ap.add_argument("--snappy", type=float, nargs="*", default=[], metavar="N",
                    help="snappyHexMesh peer, stepped tube only: about N cells across every segment (background "
                    "cell %g / N mm, one refinement level per halving of the diameter; default: none)" % DIAMETERS[0])
    ap.add_argument("--mesh3-h", type=float, nargs="*", default=[], metavar="H",
                    help="CGAL Mesh_3 peer: every size bound H mm (default: none)")
    ap.add_argument("--mesh3-radius", type=float, nargs="*", default=[], metavar="F",
                    help="CGAL Mesh_3 peer sized from the centreline: size F times the local radius, tet "
                    "edges about 1.6 F r (default: none)")
    ap.add_argument("--mesh3-surface", default=os.path.join(REPO, "build", "validation", "mesh3_surface"),
                    help="the mesh3_surface binary (default: %(default)s)")
    ap.add_argument("--quick", action="store_true",
                    help="smoke test: M = 5 only, at most %d SIMPLE iterations" % QUICK_ITERATIONS)
    ap.add_argument("--doc", metavar="PATH",
                    help="also write the results section into this page (e.g. docs/validation.md), between "
                    "the markers %s and %s (one section per geometry), appended if it has none"
                    % doc_markers("GEOMETRY"))
    ap.add_argument("--from-json", metavar="PATH",
                    help="run nothing: the section from this results JSON, into --doc or, without it, to stdout")
    args = ap.parse_args()
    # The cases run in their own directories: every path absolute.
    for name in ("scalemesh", "workdir", "out", "doc", "mesh3_surface"):
        value = getattr(args, name)
        if value and (name != "scalemesh" or os.sep in value):  # a bare name is looked up on PATH
            setattr(args, name, os.path.abspath(value))

    if args.from_json:
        with open(args.from_json) as f:
            data = json.load(f)
        section = doc_section(data)
        if args.doc:
            replace_section(args.doc, section, *doc_markers(data["geometry"]))
            log("wrote the section of %s into %s" % (args.from_json, args.doc))
        else:
            print(section)
        return 0

    geometry = GEOMETRIES[args.geometry]
    if args.snappy and geometry.name != "stepped":
        ap.error("--snappy: the stepped tube only (its inlet and outlet are the ends of snappy's block)")
    binary = os.path.abspath(args.scalemesh)
    if not os.access(binary, os.X_OK):
        sys.exit("no scalemesh binary at %s (pass --scalemesh)" % binary)
    if (args.mesh3_h or args.mesh3_radius) and not os.access(args.mesh3_surface, os.X_OK):
        sys.exit("no mesh3_surface binary at %s: build it with `cmake --build build --target mesh3_surface` "
                 "(it is not in the default target), or pass --mesh3-surface" % args.mesh3_surface)
    Ms = [5] if args.quick else args.M
    iterations = QUICK_ITERATIONS if args.quick else None
    os.makedirs(args.workdir, exist_ok=True)
    start = time.time()
    cpu, commit = machine()
    data = {"command": " ".join(["/usr/bin/python3", os.path.relpath(os.path.abspath(__file__), REPO)]
                                + sys.argv[1:]),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(start)), "cores": os.cpu_count(),
            "cpu": cpu, "commit": commit, "load_average": os.getloadavg()[0], "geometry": geometry.name,
            "max_iterations": iterations, "nu": NU, "inlet_speed": U_IN,
            "diameters_mm": sorted({b["diameter"] for b in geometry.branches()}, reverse=True)}

    stl = os.path.join(args.workdir, STL_NAME)
    data["stl_triangles"] = write_surface_stl(geometry, stl)
    if args.mesh3_h or args.mesh3_radius:
        stl_exact = os.path.join(args.workdir, "between-openings.stl")
        write_surface_stl(geometry, stl_exact, margins=False)
    log("%s: diameters %s mm, %d STL triangles"
        % (geometry.title, " / ".join("%.3g" % d for d in data["diameters_mm"]), data["stl_triangles"]))
    results = []
    for M in Ms:
        case = os.path.join(args.workdir, "scalemesh-M%g" % M)

        def make_mesh(M=M, case=case):
            seconds, report = scalemesh_case(binary, geometry, M, case, stl)
            return seconds, {"max_non_orthogonality_deg": report.get("max_non_orthogonality_deg")}
        results.append(study_one(geometry, "scalemesh", M, case, make_mesh, iterations))
    template = results[0]["case"]
    makers = {
        "gmsh": lambda h, case: (gmsh_case(geometry, gmsh_uniform(h), case, template), {}),
        "gmsh-curvature": lambda n, case: (gmsh_case(geometry, gmsh_curvature(n), case, template), {}),
        "snappy": lambda n, case: snappy_case(n, case, template, stl),
        "mesh3": lambda h, case: (mesh3_case(geometry, args.mesh3_surface, mesh3_sizes(geometry, "mesh3", h), case,
                                             template, stl_exact), {}),
        "mesh3-radius": lambda f, case: (mesh3_case(geometry, args.mesh3_surface,
                                                    mesh3_sizes(geometry, "mesh3-radius", f), case, template,
                                                    stl_exact), {}),
    }
    for mesher, params in (("gmsh", args.gmsh_h), ("gmsh-curvature", args.gmsh_curvature), ("snappy", args.snappy),
                           ("mesh3", args.mesh3_h), ("mesh3-radius", args.mesh3_radius)):
        for param in params:
            case = os.path.join(args.workdir, "%s-%s%g" % (mesher, MESHERS[mesher][2], param))
            results.append(study_one(geometry, mesher, param, case,
                                     lambda m=makers[mesher], p=param, c=case: m(p, c), iterations))

    data["results"] = results
    data["seconds"] = time.time() - start
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump(data, f, indent=1)
    log("\n%s\n\n%s\n\n%s\n" % (table(results), summary_table(results),
                                claim(results, geometry.piece, geometry.pieces)))
    if args.doc:
        replace_section(args.doc, doc_section(data), *doc_markers(geometry.name))
        log("wrote the section into %s" % args.doc)
    log("wrote %s in %.0f s" % (args.out, data["seconds"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
