#!/usr/bin/python3
"""Netgen as a peer of scalemesh: a tet mesh of a closed STL with prism wall
layers, as an OpenFOAM case.

netgen_case(stl, openings, case, template, maxh, ...) meshes the closed STL
(mm; the geometry between its openings, closed by flat discs on the
openings' planes, as the CGAL Mesh_3 peer gets it) with Netgen's STL
geometry (Debian 12's python3-netgen, Netgen 6.2.1905), adds prism layers on
the wall with Netgen's Mesh.BoundaryLayer, labels the boundary (a face whose
centroid lies on an opening's plane, within its radius, belongs to that
opening; every other face to `wall`), writes a Gmsh 2.2 ASCII file and
converts it as tube_validation.foam_from_msh does (gmshToFoam, scaled to
metres, the wall patch made a `wall`), with the template's system/,
constant/ and 0/.

The meshing runs in a child process (this file run as a script), so that
Netgen's console output goes to CASE/log.netgen, its debugging file
(BndLayerDebug.log, which the boundary layer code writes into the working
directory) into the case, its global STL options are fresh for every mesh,
and a crash of Netgen is a failed run rather than a dead harness.

Settings (Netgen 6.2.1905, as a user of its GUI would set them; its Python
interface passes less of them on to the STL pipeline):
  * Size bound maxh, grading. MeshingParameters(maxh, grading) go to the
    STL driver, but its atlas step resets the mesh's size bound from the
    library's global MeshingParameters (netgen::mparam, which the GUI's
    meshing options set and Python does not; maxh 1e10 by default), so
    given only to GenerateMesh maxh hardly bounds the surface (0.8 gave
    1.9 mm facets on the 8 mm tube). The child writes maxh and grading into
    the global too (ctypes; offsets of meshing/meshtype.hpp checked against
    the defaults first); then facets come out at about maxh. Grading is
    Netgen's default 0.3 (how fast the size may grow away from a small
    one, here from the wall into the core).
  * Curvature (curvature=F). MeshingParameters' curvaturesafety and
    segmentsperedge are accepted but read only by the CSG, OCC and 2D
    geometries; the STL geometry's own sizes are its global STLParameters
    (netgen::stlparam, the GUI's STL options). Among them "restrict h by
    surface curvature" (resthsurfcurvenable, off by default; factor
    resthsurfcurvfac): along every facet edge h <= r / F, r the radius of
    the cylinder through the two facets, so about 2 pi F elements around
    and 2 F across a tube of any diameter (facet edges came out at about
    1.1 r / F): Netgen's scale-aware setting for an STL, the analogue of
    Gmsh's MeshSizeFromCurvature with N = 2 pi F. The child switches it on
    through ctypes (the layout of stlgeom/stltool.hpp, checked against the
    defaults first). curvature=None: maxh sets the size, with Netgen's
    default STL restrictions (chart distances, short feature lines), which
    made 0.42 mm facets in the 1 mm tube at maxh 0.8.
  * Wall layers. Mesh.BoundaryLayer(bc, thickness, domain, material) of
    6.2.1905 (GenerateBoundaryLayer) moves the surface points of the faces
    whose bc is `bc` inward along their averaged normals by `thickness`,
    compressing the tets behind them, and fills the gap with prisms; points
    on the mesh's feature edges (here the rims of the opening discs) stay,
    so the layer thins to nothing at the openings (tets and pyramids
    there). One absolute thickness for the whole wall: nothing relative to
    the local cells as snappyHexMesh's relativeSizes. Its list overload
    (one height per layer) re-attaches the earlier layers' prisms to the new
    wall points, so they overlap; the layers are therefore added one call
    at a time, outermost first, each call's height the distance of its
    layer's inner side from the wall (a call moves the earlier layers' wall
    side inward with the bulk, so each earlier layer keeps the difference),
    the new prisms returned to the bulk domain between calls. Then Netgen's
    volume optimisation (Mesh.OptimizeVolumeMesh: 5 passes of combine,
    split, smooth and swap; the layers' points are locked) mends the
    compressed tets. Thicknesses: the wall layer first_layer mm, each next
    one `growth` times the one before (1.2, snappyHexMesh's expansion ratio
    here). first_layer=None: a total of LAYER_SHARE of the wall tets'
    height (the 5th percentile of the height of each wall tet's inner
    vertex above its wall face, set by the narrowest tube), as thick as the
    compressed tets allow: thinner than snappyHexMesh's relative layers
    (1.26 cells) everywhere, a small fraction of a cell in the wide tubes.
    If an element still comes out inverted the thickness is halved and the
    layers redone (at most LAYER_TRIES times), then dropped (a tet-only
    mesh; netgen_layers 0 in the figures).
"""

import argparse
import json
import math
import os
import struct
import sys
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import log, run  # noqa: E402
from tube_validation import case_from_template, foam_from_msh  # noqa: E402

MSH_NAME = "tube.msh"
STATS_NAME = "netgen_stats.json"
GRADING = 0.3         # Netgen's default
LAYER_SHARE = 0.5     # first_layer=None: total layer thickness / a small wall tet's height
LAYER_TRIES = 4       # halvings of the layer thickness before giving the layers up


def netgen_case(stl, openings, case, template, maxh, layers=3, first_layer=None, growth=1.2, curvature=None,
                grading=GRADING):
    """A Netgen mesh of the closed STL `stl` (mm) as an OpenFOAM case with
    the template's system/, constant/ and 0/: elements of at most maxh mm,
    if `curvature` sized from the STL's curvature too (h <= r / curvature),
    `layers` prism layers on the wall (0: none; first_layer mm at the wall,
    growing by `growth`; None: from the wall tets), the boundary labelled
    from `openings` ((name, type, point, outward normal, radius) in mm;
    radius 0: the crossing of the plane nearest the point). Returns (the
    seconds, meshing and conversion to a polyMesh, and a dict of figures:
    netgen_cells, netgen_prisms, netgen_pyramids, netgen_tets, netgen_layers
    (0 if none could be added), netgen_layer_mm (their total thickness),
    netgen_first_layer_mm, netgen_layer_tries, the wall tets' heights and
    Netgen's own seconds)."""
    case_from_template(case, template)
    args = {"stl": os.path.abspath(stl), "maxh": maxh, "grading": grading, "curvature": curvature,
            "layers": layers, "first_layer": first_layer, "growth": growth,
            "openings": [[name, kind, list(point), list(normal), radius]
                         for name, kind, point, normal, radius in openings]}
    with open(os.path.join(case, "netgen_args.json"), "w") as f:
        json.dump(args, f, indent=1)
    t = time.time()
    run([sys.executable, os.path.abspath(__file__), "netgen_args.json"], case, "log.netgen")
    foam_from_msh(case, MSH_NAME)
    seconds = time.time() - t
    with open(os.path.join(case, STATS_NAME)) as f:
        stats = json.load(f)
    log("Netgen maxh %g curvature %s: %d cells (%d prisms), layers %g mm" % (
        maxh, curvature, stats["netgen_cells"], stats["netgen_prisms"], stats["netgen_layer_mm"]))
    return seconds, stats


# ------------------------------------------------ the child: Netgen itself

def ascii_stl(src, dst):
    """`src` (binary or ASCII STL) as an ASCII STL: Netgen 6.2.1905's
    LoadSTLGeometry reads ASCII only."""
    with open(src, "rb") as f:
        data = f.read()
    n = struct.unpack_from("<I", data, 80)[0] if len(data) >= 84 else -1
    if len(data) != 84 + 50 * n:    # not binary
        with open(dst, "wb") as f:
            f.write(data)
        return
    with open(dst, "w") as f:
        f.write("solid surface\n")
        for i in range(n):
            v = struct.unpack_from("<12f", data, 84 + 50 * i)
            f.write("facet normal %.9g %.9g %.9g\nouter loop\n" % v[:3])
            for k in range(3):
                f.write("vertex %.9g %.9g %.9g\n" % v[3 + 3 * k:6 + 3 * k])
            f.write("endloop\nendfacet\n")
        f.write("endsolid surface\n")


def netgen_global(library, symbol):
    """The address of a global variable of one of the Netgen libraries the
    netgen module has loaded (library: its file name's start, "libstl")."""
    import ctypes
    import netgen.meshing
    import netgen.stl
    del netgen  # imported only to load the libraries (libstl among them)

    with open("/proc/self/maps") as f:
        paths = [line.split(None, 5)[5].strip() for line in f if len(line.split(None, 5)) == 6]
    for path in paths:
        if os.path.basename(path).startswith(library + ".so"):
            return ctypes.addressof(ctypes.c_char.in_dll(ctypes.CDLL(path), symbol))
    raise RuntimeError("the netgen module has not loaded %s" % library)


def set_global_size(maxh, grading):
    """maxh and grading in Netgen's global MeshingParameters (netgen::mparam,
    what the GUI's meshing options set): the STL pipeline of 6.2.1905 reads
    the size bound from it (its atlas step resets the mesh's global h to
    mparam.maxh, 1e10 by default) rather than from the MeshingParameters
    GenerateMesh is given. Offsets from meshing/meshtype.hpp (x86-64,
    std::string of 32 bytes), checked against the defaults first."""
    import ctypes

    base = netgen_global("libinterface", "_ZN6netgen6mparamE")
    fields = {"optsteps3d": (32, ctypes.c_int, 3), "optsteps2d": (72, ctypes.c_int, 3),
              "opterrpow": (80, ctypes.c_double, 2.0), "safety": (104, ctypes.c_double, 5.0),
              "uselocalh": (120, ctypes.c_int, 1), "grading": (128, ctypes.c_double, 0.3),
              "delaunay": (136, ctypes.c_int, 1), "maxh": (144, ctypes.c_double, 1e10)}
    found = {k: t.from_address(base + off).value for k, (off, t, _) in fields.items()}
    if any(found[k] != v for k, (_, _, v) in fields.items()):
        raise RuntimeError("netgen::mparam is not laid out as in Netgen 6.2.1905: %s" % found)
    ctypes.c_double.from_address(base + 144).value = maxh
    ctypes.c_double.from_address(base + 128).value = grading


def set_surface_curvature(factor):
    """Netgen's STL option "restrict h by surface curvature" (h <= r /
    factor), which 6.2.1905 exposes to the GUI only: written into the global
    netgen::stlparam (stlgeom/stltool.hpp), checked against the defaults
    first."""
    import ctypes

    names = ["yangle", "contyangle", "edgecornerangle", "chartangle", "outerchartangle", "usesearchtree",
             "resthatlasfac", "resthatlasenable", "atlasminh", "resthsurfcurvfac", "resthsurfcurvenable",
             "resthchartdistfac", "resthchartdistenable", "resthcloseedgefac", "resthcloseedgeenable",
             "resthedgeanglefac", "resthedgeangleenable", "resthsurfmeshcurvfac", "resthsurfmeshcurvenable",
             "resthlinelengthfac", "resthlinelengthenable", "recalc_h_opt"]
    ints = {"usesearchtree", "resthatlasenable", "resthsurfcurvenable", "resthchartdistenable",
            "resthcloseedgeenable", "resthedgeangleenable", "resthsurfmeshcurvenable", "resthlinelengthenable",
            "recalc_h_opt"}

    class STLParameters(ctypes.Structure):
        _fields_ = [(n, ctypes.c_int if n in ints else ctypes.c_double) for n in names]

    p = STLParameters.from_address(netgen_global("libstl", "_ZN6netgen8stlparamE"))
    expected = {"yangle": 30, "contyangle": 20, "edgecornerangle": 60, "chartangle": 15, "outerchartangle": 70,
                "resthatlasfac": 2, "resthsurfcurvenable": 0, "resthchartdistfac": 1.2, "resthlinelengthfac": 0.5,
                "recalc_h_opt": 1}
    found = {k: getattr(p, k) for k in expected}
    if any(abs(found[k] - v) > 1e-12 for k, v in expected.items()):
        raise RuntimeError("netgen::stlparam is not laid out as in Netgen 6.2.1905: %s" % found)
    p.resthsurfcurvfac = factor
    p.resthsurfcurvenable = 1


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def centroid(ps):
    return tuple(sum(p[k] for p in ps) / len(ps) for k in range(3))


def surface_labels(mesh, openings):
    """The patch name of every face descriptor of the Netgen mesh: an
    opening's where its surface elements' centroids lie on the opening's
    plane (within 1e-5 of the mesh's size) and radius (radius 0: of the
    face descriptors on the plane, the one whose centroid is nearest the
    opening's point), `wall` elsewhere. Raises if a face descriptor mixes
    patches (Netgen did not separate a disc from the wall)."""
    pts = mesh.Points()
    els = [(el.index, [pts[v].p for v in el.vertices]) for el in mesh.Elements2D()]
    lo = [min(p[k] for _, ps in els for p in ps) for k in range(3)]
    hi = [max(p[k] for _, ps in els for p in ps) for k in range(3)]
    tol = 1e-5 * math.dist(lo, hi)
    planes = []
    for name, _, point, normal, radius in openings:
        n = math.sqrt(dot(normal, normal))
        planes.append((name, tuple(point), tuple(c / n for c in normal), radius))
    label = []
    for _, ps in els:
        c = centroid(ps)
        hit = None
        for name, point, normal, radius in planes:
            d = dot(sub(c, point), normal)
            if abs(d) < tol:
                off = sub(sub(c, point), tuple(d * x for x in normal))
                if radius == 0 or math.sqrt(dot(off, off)) <= radius:
                    hit = name
        label.append(hit)
    # Openings without a radius: the face descriptor nearest the point.
    for name, point, _, radius in planes:
        if radius:
            continue
        sums = {}
        for (fd, ps), lab in zip(els, label):
            if lab == name:
                s = sums.setdefault(fd, [0.0, 0.0, 0.0, 0])
                c = centroid(ps)
                for k in range(3):
                    s[k] += c[k]
                s[3] += 1
        if sums:
            best = min(sums, key=lambda fd: math.dist([v / sums[fd][3] for v in sums[fd][:3]], point))
            label = [None if lab == name and fd != best else lab for (fd, _), lab in zip(els, label)]
    names = {}
    for (fd, _), lab in zip(els, label):
        names.setdefault(fd, set()).add(lab or "wall")
    for fd, s in names.items():
        if len(s) != 1:
            raise RuntimeError("Netgen face %d mixes the patches %s" % (fd, sorted(s)))
    missing = [p[0] for p in planes if not any(p[0] in s for s in names.values())]
    if missing:
        raise RuntimeError("no boundary face on the opening(s) %s" % missing)
    return {fd: s.pop() for fd, s in names.items()}


def oriented(vs, pts):
    """The element's vertices in Gmsh's order and orientation: a tet with
    a positive volume, a prism's or a pyramid's base turning (right hand)
    towards its top or apex. (Flat or inverted elements are element_check's
    to find.)"""
    p = [pts[v] for v in vs]
    if len(vs) == 4:
        if dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), sub(p[3], p[0])) < 0:
            vs = [vs[0], vs[2], vs[1], vs[3]]
    elif len(vs) == 6:
        if dot(cross(sub(p[1], p[0]), sub(p[2], p[0])), sub(centroid(p[3:]), centroid(p[:3]))) < 0:
            vs = [vs[0], vs[2], vs[1], vs[3], vs[5], vs[4]]
    elif len(vs) == 5:
        if dot(cross(sub(p[2], p[0]), sub(p[3], p[1])), sub(p[4], centroid(p[:4]))) < 0:
            vs = [vs[0], vs[3], vs[2], vs[1], vs[4]]
    else:
        raise RuntimeError("a Netgen volume element with %d vertices" % len(vs))
    return vs


def element_check(mesh):
    """The counts of tets, pyramids and prisms, and the number of elements
    that are flat or turned inside out: tets whose signed volume is zero or
    of the minority's sign, prisms and pyramids whose corners' tets (a
    corner and its three neighbours in the element) do not all turn the
    same way."""
    P = mesh.Points()
    counts = {4: 0, 5: 0, 6: 0}
    signs = [0, 0, 0]     # tets with a negative, zero, positive volume
    bad = 0
    corners = {6: [(0, 1, 2, 3), (1, 2, 0, 4), (2, 0, 1, 5), (3, 5, 4, 0), (4, 3, 5, 1), (5, 4, 3, 2)],
               5: [(0, 1, 3, 4), (1, 2, 0, 4), (2, 3, 1, 4), (3, 0, 2, 4)]}
    for el in mesh.Elements3D():
        q = [P[v].p for v in el.vertices]
        counts[len(q)] = counts.get(len(q), 0) + 1
        if len(q) == 4:
            det = dot(cross(sub(q[1], q[0]), sub(q[2], q[0])), sub(q[3], q[0]))
            signs[(det > 0) - (det < 0) + 1] += 1
        else:
            turns = [dot(cross(sub(q[b], q[a]), sub(q[c], q[a])), sub(q[d], q[a])) for a, b, c, d in corners[len(q)]]
            if not (all(t > 0 for t in turns) or all(t < 0 for t in turns)):
                bad += 1
    return counts.get(4, 0), counts.get(5, 0), counts.get(6, 0), bad + signs[1] + min(signs[0], signs[2])


def wall_tet_height(mesh, wall_fds, percentile=0.05):
    """The `percentile` of the heights of the wall tets: for each wall
    triangle, the distance of the inner vertex of its tet from its plane."""
    P = mesh.Points()
    faces = {}
    for el in mesh.Elements2D():
        if el.index in wall_fds:
            faces[frozenset(v.nr for v in el.vertices)] = [P[v].p for v in el.vertices]
    heights = []
    for el in mesh.Elements3D():
        vs = [v.nr for v in el.vertices]
        if len(vs) != 4:
            continue
        for k in range(4):
            key = frozenset(vs[:k] + vs[k + 1:])
            if key in faces:
                a, b, c = faces[key]
                n = cross(sub(b, a), sub(c, a))
                h = abs(dot(sub(P[el.vertices[k]].p, a), n)) / math.sqrt(dot(n, n))
                heights.append(h)
    heights.sort()
    if not heights:
        raise RuntimeError("no tet over the wall")
    return heights[int(percentile * (len(heights) - 1))], heights[0], len(heights)


def add_layers(mesh, wall_bc, thicknesses):
    """`thicknesses` (mm, from the wall inward) of prism layers on the faces
    whose bc is wall_bc, with Netgen's BoundaryLayer: one call per layer,
    the outermost first, each at its inner side's distance from the wall;
    the new prisms back in domain 1 between calls so that the next call
    moves their wall side with the bulk."""
    depths = [sum(thicknesses[:k + 1]) for k in range(len(thicknesses))]
    for depth in reversed(depths):
        mesh.BoundaryLayer(wall_bc, depth, 1, "layer")
        for el in mesh.Elements3D():
            if el.index != 1:
                el.index = 1


def write_msh(mesh, labels, path):
    """The mesh as a Gmsh 2.2 ASCII file (mm): its points, the boundary
    triangles and quads in the physical surface of their face descriptor's
    patch (`labels`; wall first, then the openings by name), the tets,
    prisms and pyramids in one physical volume `fluid`."""
    P = mesh.Points()
    vols = [[v.nr for v in el.vertices] for el in mesh.Elements3D()]
    surfs = [(el.index, [v.nr for v in el.vertices]) for el in mesh.Elements2D()]
    coords = {}
    for el in list(mesh.Elements3D()) + list(mesh.Elements2D()):
        for v in el.vertices:
            if v.nr not in coords:
                coords[v.nr] = P[v].p
    patches = ["wall"] + sorted(set(labels.values()) - {"wall"})
    tag = {name: i + 1 for i, name in enumerate(patches)}
    fluid = len(patches) + 1
    numbers = {v: i + 1 for i, v in enumerate(sorted(coords))}
    lines = []
    for fd, vs in surfs:
        t = tag[labels[fd]]
        lines.append("%d 2 %d %d %s" % ({3: 2, 4: 3}[len(vs)], t, t, " ".join(str(numbers[v]) for v in vs)))
    for vs in vols:
        vs = oriented(vs, coords)
        lines.append("%d 2 %d %d %s" % ({4: 4, 6: 6, 5: 7}[len(vs)], fluid, fluid,
                                        " ".join(str(numbers[v]) for v in vs)))
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n%d\n" % (len(patches) + 1))
        for name in patches:
            f.write('2 %d "%s"\n' % (tag[name], name))
        f.write('3 %d "fluid"\n$EndPhysicalNames\n$Nodes\n%d\n' % (fluid, len(numbers)))
        for v, k in numbers.items():
            f.write("%d %.12g %.12g %.12g\n" % ((k,) + tuple(coords[v])))
        f.write("$EndNodes\n$Elements\n%d\n" % len(lines))
        for i, line in enumerate(lines):
            f.write("%d %s\n" % (i + 1, line))
        f.write("$EndElements\n")


def mesh_main(args_path):
    """The child: meshes as the arguments file says, writes MSH_NAME and
    STATS_NAME into the working directory (the case)."""
    with open(args_path) as f:
        a = json.load(f)
    import netgen.meshing as meshing
    import netgen.stl as ngstl

    meshing.SetMessageImportance(3)
    t0 = time.time()
    ascii_stl(a["stl"], "netgen_surface.stl")
    set_global_size(a["maxh"], a["grading"])
    if a["curvature"]:
        set_surface_curvature(a["curvature"])
    geo = ngstl.LoadSTLGeometry("netgen_surface.stl")
    os.remove("netgen_surface.stl")
    mp = meshing.MeshingParameters(maxh=a["maxh"], grading=a["grading"])
    mesh = ngstl.GenerateMesh(geo, mp)
    if len(mesh.Elements3D()) == 0:
        raise RuntimeError("Netgen made no volume mesh (see log.netgen)")
    t_volume = time.time() - t0
    print("netgen: %d tets, %d surface elements, %.1f s" % (len(mesh.Elements3D()), len(mesh.Elements2D()),
                                                            t_volume), flush=True)
    labels = surface_labels(mesh, a["openings"])
    patches = ["wall"] + sorted(set(labels.values()) - {"wall"})
    for fd, name in labels.items():
        mesh.FaceDescriptor(fd).bc = patches.index(name) + 1
        mesh.SetBCName(patches.index(name), name)
    wall_fds = {fd for fd, name in labels.items() if name == "wall"}
    _, _, _, bad = element_check(mesh)
    if bad:
        raise RuntimeError("Netgen's tet mesh has %d inverted elements" % bad)
    stats = {"netgen_layer_mm": 0.0, "netgen_layer_tries": 0, "netgen_layers": 0}
    n = a["layers"]
    if n:
        h5, hmin, _ = wall_tet_height(mesh, wall_fds)
        stats["netgen_wall_tet_height_p5_mm"] = h5
        stats["netgen_wall_tet_height_min_mm"] = hmin
        g = a["growth"]
        shape = [g ** k for k in range(n)]
        first = a["first_layer"] or LAYER_SHARE * h5 / sum(shape)
        for attempt in range(LAYER_TRIES + 1):
            trial = mesh.Copy()
            thicknesses = [first * s for s in shape]
            add_layers(trial, 1, thicknesses)
            _, _, _, bad = element_check(trial)
            # Netgen's volume optimisation (5 passes of its default
            # combine, split, smooth and swap steps; the layers' points are
            # locked) mends the tets compressed behind the layers.
            trial.OptimizeVolumeMesh()
            _, _, _, bad_after = element_check(trial)
            print("netgen: layers of %s mm: %d inverted elements, %d after optimisation"
                  % (["%.4g" % t for t in thicknesses], bad, bad_after), flush=True)
            bad = bad_after
            stats["netgen_layer_tries"] = attempt + 1
            if not bad:
                mesh = trial
                stats["netgen_layer_mm"] = sum(thicknesses)
                stats["netgen_first_layer_mm"] = first
                stats["netgen_layers"] = n
                break
            first /= 2
        else:
            print("netgen: no valid layers; the tet mesh without them", flush=True)
    if os.path.exists("BndLayerDebug.log") and not os.path.getsize("BndLayerDebug.log"):
        os.remove("BndLayerDebug.log")
    tets, pyramids, prisms, bad = element_check(mesh)
    if bad:
        raise RuntimeError("%d inverted elements in the Netgen mesh" % bad)
    write_msh(mesh, labels, MSH_NAME)
    stats.update({"netgen_tets": tets, "netgen_pyramids": pyramids, "netgen_prisms": prisms,
                  "netgen_cells": tets + pyramids + prisms, "netgen_points": len(mesh.Points()),
                  "netgen_seconds": time.time() - t0, "netgen_volume_seconds": t_volume})
    with open(STATS_NAME, "w") as f:
        json.dump(stats, f, indent=1)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description="the Netgen child of netgen_case (an arguments file)")
    parser.add_argument("args")
    mesh_main(parser.parse_args().args)
