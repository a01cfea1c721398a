"""Helpers shared by the CFD validation harnesses (tube_validation.py,
curved_validation.py): running OpenFOAM tools, reading ASCII OpenFOAM fields
and the boundary faces of a polyMesh, and writing docs/validation.md without
losing the sections another harness generated. python3 stdlib only."""

import math
import os
import platform
import re
import shutil
import subprocess
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def log(msg):
    print(msg, flush=True)


def run(cmd, cwd, logname, nice=False):
    """Runs `cmd` (a list) in `cwd`, output into cwd/logname; raises on failure."""
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    env["PWD"] = os.path.abspath(cwd)  # else OpenFOAM warns on every line
    if nice:
        cmd = ["nice", "-n", "10"] + cmd
    with open(os.path.join(cwd, logname), "w") as out:
        code = subprocess.call(cmd, cwd=cwd, stdout=out, stderr=subprocess.STDOUT, env=env)
    text = open(os.path.join(cwd, logname)).read()
    if code != 0:
        raise RuntimeError("%s failed (exit %d) in %s:\n%s" % (" ".join(cmd), code, cwd, text[-3000:]))
    return text


# ---------------------------------------------------------------- OpenFOAM

def solve(case):
    """simpleFoam to convergence, then the wall shear stress, cell centres and
    cell volumes of the last iteration."""
    check = run(["checkMesh", "-case", "."], case, "log.checkMesh")
    mesh_ok = "Mesh OK." in check
    t = time.time()
    text = run(["simpleFoam", "-case", "."], case, "log.simpleFoam", nice=True)
    seconds = time.time() - t
    m = re.search(r"SIMPLE solution converged in (\d+) iterations", text)
    iterations = int(m.group(1)) if m else len(re.findall(r"(?m)^Time = ", text))
    run(["simpleFoam", "-case", ".", "-postProcess", "-latestTime", "-func", "wallShearStress"],
        case, "log.wallShearStress", nice=True)
    run(["postProcess", "-case", ".", "-latestTime", "-func", "writeCellCentres"], case, "log.cellCentres")
    run(["postProcess", "-case", ".", "-latestTime", "-func", "writeCellVolumes"], case, "log.cellVolumes")
    return {"converged": m is not None, "iterations": iterations, "solver_seconds": seconds, "mesh_ok": mesh_ok}


def latest_time(case):
    best, path = -1.0, None
    for name in os.listdir(case):
        try:
            t = float(name)
        except ValueError:
            continue
        if t > best:
            best, path = t, os.path.join(case, name)
    return path


def read_list(text, at, components):
    """The ASCII OpenFOAM list starting at or after text[at]: its count, then
    ( ... ). Returns floats (scalars) or tuples (vectors)."""
    m = re.compile(r"(\d+)\s*\(").search(text, at)
    n = int(m.group(1))
    body_start = m.end()
    end = text.index(")\n;", body_start) if components == 1 else None
    if components == 1:
        values = [float(v) for v in text[body_start:end].split()]
    else:
        values = []
        pos = body_start
        pat = re.compile(r"\(([^()]*)\)")
        for mm in pat.finditer(text, pos):
            values.append(tuple(float(v) for v in mm.group(1).split()))
            if len(values) == n:
                break
    if len(values) != n:
        raise RuntimeError("list of %d read as %d" % (n, len(values)))
    return values


def internal_field(path, components):
    text = open(path).read()
    at = text.index("internalField")
    if "nonuniform" not in text[at:at + 60]:
        raise RuntimeError("a uniform internalField in " + path)
    return read_list(text, at, components)


def patch_field(path, patch, components):
    text = open(path).read()
    m = re.search(r"\n\s*%s\s*\{[^}]*?value\s+nonuniform" % re.escape(patch), text)
    if not m:
        raise RuntimeError("no nonuniform value of patch %s in %s" % (patch, path))
    return read_list(text, m.end(), components)


def foam_list_lines(path):
    """The entries of an ASCII polyMesh list file, one per line."""
    lines = open(path).read().split("\n")
    i = 0
    while not re.fullmatch(r"\s*\d+\s*", lines[i]) or lines[i + 1].strip() != "(":
        i += 1
    n = int(lines[i])
    return lines[i + 2:i + 2 + n]


def read_points(path):
    """The points of an ASCII polyMesh points file: (x, y, z) tuples."""
    return [tuple(float(v) for v in line.strip()[1:-1].split()) for line in foam_list_lines(path)]


def read_faces(path):
    """The faces of an ASCII polyMesh faces file: point index lists."""
    text = open(path).read()
    m = re.search(r"\n(\d+)\s*\n\s*\(", text)
    # Each face is n(a b c ...), on one line or, when long, on several.
    tokens = text[m.end():].replace("(", " ( ").replace(")", " ) ").split()
    faces, i = [], 0
    while len(faces) < int(m.group(1)) and i < len(tokens):
        n = int(tokens[i])
        faces.append([int(v) for v in tokens[i + 2:i + 2 + n]])
        i += n + 3
    if len(faces) != int(m.group(1)):
        raise RuntimeError("faces: %d of %s read" % (len(faces), m.group(1)))
    return faces


def read_polymesh(case):
    """The case's ASCII polyMesh: points (metres, tuples), faces (point
    index lists), owner and neighbour (cell per face; neighbour for the
    interior faces only)."""
    poly = os.path.join(case, "constant", "polyMesh")
    points = read_points(os.path.join(poly, "points"))
    faces = read_faces(os.path.join(poly, "faces"))
    owner, neighbour = ([int(line) for line in foam_list_lines(os.path.join(poly, name))]
                        for name in ("owner", "neighbour"))
    return points, faces, owner, neighbour


def have_gnuplot():
    """Whether gnuplot is on the PATH (said in the log when it is not)."""
    if shutil.which("gnuplot"):
        return True
    log("no gnuplot: no plot")
    return False


def write_series(path, rows):
    """A gnuplot data file at `path`: one line per row of numbers, an int as
    %d, a float as %g, None as NaN (so pass cell counts as ints and
    measured values as floats). Returns the path."""
    with open(path, "w") as f:
        for row in rows:
            f.write(" ".join("NaN" if v is None else "%d" % v if isinstance(v, int) else "%g" % v
                             for v in row) + "\n")
    return path


def run_gnuplot(script, path):
    """Writes the gnuplot `script` to `path` and runs it. Returns True."""
    with open(path, "w") as f:
        f.write(script)
    subprocess.check_call(["gnuplot", path])
    return True


def cpu_model():
    """The CPU's model name, or what platform knows."""
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def boundary_faces(case):
    """Per patch: a list of (centre, area vector) of its faces, in metres."""
    poly = os.path.join(case, "constant", "polyMesh")
    points = read_points(os.path.join(poly, "points"))
    faces = read_faces(os.path.join(poly, "faces"))
    text = open(os.path.join(poly, "boundary")).read()
    patches = {}
    for m in re.finditer(r"\n\s*(\w+)\s*\{([^}]*)\}", text):
        body = m.group(2)
        if "nFaces" not in body:
            continue  # the FoamFile header
        n = int(re.search(r"nFaces\s+(\d+)", body).group(1))
        start = int(re.search(r"startFace\s+(\d+)", body).group(1))
        out = []
        for face in faces[start:start + n]:
            ps = [points[k] for k in face]
            c = tuple(sum(p[j] for p in ps) / len(ps) for j in range(3))
            a = [0.0, 0.0, 0.0]
            for k in range(len(ps)):
                p, q = ps[k], ps[(k + 1) % len(ps)]
                u = [p[j] - c[j] for j in range(3)]
                v = [q[j] - c[j] for j in range(3)]
                a[0] += 0.5 * (u[1] * v[2] - u[2] * v[1])
                a[1] += 0.5 * (u[2] * v[0] - u[0] * v[2])
                a[2] += 0.5 * (u[0] * v[1] - u[1] * v[0])
            out.append((c, tuple(a)))
        patches[m.group(1)] = out
    zs = [p[2] for p in points]
    return patches, min(zs), max(zs)


# ------------------------------------------------------ snappyHexMesh peer


SNAPPY_HEAD = "FoamFile { version 2.0; format ascii; class dictionary; object %s; }\n"


def write_block_mesh_dict(case, lo, hi, n, boundary):
    """system/blockMeshDict: one block of n = (nx, ny, nz) cells from corner
    lo to corner hi (x, y, z), its vertices numbered as blockMesh's hex (0 1
    2 3 4 5 6 7), and `boundary` the text inside boundary ( ... )."""
    with open(os.path.join(case, "system", "blockMeshDict"), "w") as f:
        f.write(SNAPPY_HEAD % "blockMeshDict")
        f.write("convertToMeters 1;\nvertices (")
        for z in (lo[2], hi[2]):
            for x, y in ((lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])):
                f.write(" (%.9g %.9g %.9g)" % (x, y, z))
        f.write(" );\nblocks ( hex (0 1 2 3 4 5 6 7) (%d %d %d) simpleGrading (1 1 1) );\nedges ();\n"
                "boundary (%s);\n" % (tuple(n) + (boundary,)))


def write_snappy_dict(case, geometry, surfaces, regions, location, layers):
    """system/snappyHexMeshDict: `geometry` the text inside geometry { ... },
    `surfaces` inside refinementSurfaces { ... }, `regions` inside
    refinementRegions { ... }, `location` the locationInMesh point, and
    `layers` wall layers on the patch named wall (relative sizes, expansion
    ratio 1.2, the last layer 0.5 of the cell next to it), as
    snappyHexMesh's tutorials set them. `location` may also be a list of
    points, one in each of the mesh's disconnected regions: then
    locationsInMesh, each region a cellZone region0, region1, ..."""
    if isinstance(location[0], (tuple, list)):
        where = "locationsInMesh (%s);" % " ".join("((%.9g %.9g %.9g) region%d)" % (tuple(p) + (i,))
                                                   for i, p in enumerate(location))
    else:
        where = "locationInMesh (%.9g %.9g %.9g);" % tuple(location)
    with open(os.path.join(case, "system", "snappyHexMeshDict"), "w") as f:
        f.write(SNAPPY_HEAD % "snappyHexMeshDict")
        f.write("castellatedMesh true; snap true; addLayers true;\n"
                "geometry {\n%s}\n"
                "castellatedMeshControls {\n"
                "  maxLocalCells 100000000; maxGlobalCells 200000000; minRefinementCells 0; maxLoadUnbalance 0.1;\n"
                "  nCellsBetweenLevels 3; features ();\n"
                "  refinementSurfaces {%s}\n"
                "  resolveFeatureAngle 30;\n  refinementRegions {\n%s  }\n"
                "  %s allowFreeStandingZoneFaces true;\n}\n"
                "snapControls { nSmoothPatch 3; tolerance 2.0; nSolveIter 100; nRelaxIter 5; nFeatureSnapIter 10;\n"
                "  implicitFeatureSnap true; explicitFeatureSnap false; multiRegionFeatureSnap false; }\n"
                "addLayersControls {\n"
                "  relativeSizes true; layers { wall { nSurfaceLayers %d; } }\n"
                "  expansionRatio 1.2; finalLayerThickness 0.5; minThickness 0.1; nGrow 0; featureAngle 60;\n"
                "  slipFeatureAngle 30; nRelaxIter 3; nSmoothSurfaceNormals 1; nSmoothNormals 3; nSmoothThickness 10;\n"
                "  maxFaceThicknessRatio 0.5; maxThicknessToMedialRatio 0.3; minMedialAxisAngle 90;\n"
                "  nBufferCellsNoExtrude 0; nLayerIter 50;\n}\n"
                "meshQualityControls {\n"
                "  maxNonOrtho 65; maxBoundarySkewness 20; maxInternalSkewness 4; maxConcave 80; minVol 1e-13;\n"
                "  minTetQuality 1e-15; minArea -1; minTwist 0.02; minDeterminant 0.001; minFaceWeight 0.05;\n"
                "  minVolRatio 0.01; minTriangleTwist -1; nSmoothScale 4; errorReduction 0.75;\n"
                "  relaxed { maxNonOrtho 75; }\n}\n"
                "writeFlags ( ); mergeTolerance 1e-6;\n"
                % (geometry, surfaces, regions, where, layers))


def run_snappy(case):
    """blockMesh and snappyHexMesh on the case (its dictionaries written),
    then scaled from mm to metres. Returns the seconds taken and
    snappyHexMesh's layer figures for the patch wall: the layers on average
    and the percentage of the asked thickness."""
    t = time.time()
    run(["blockMesh", "-case", "."], case, "log.blockMesh")
    run(["snappyHexMesh", "-case", ".", "-overwrite"], case, "log.snappyHexMesh")
    layers, thickness = snappy_layers(case)
    run(["transformPoints", "-case", ".", "-scale", "(1e-3 1e-3 1e-3)"], case, "log.transformPoints")
    return time.time() - t, layers, thickness


def snappy_layers(case):
    """From the case's log.snappyHexMesh: the patch wall's layers on average
    and the percentage of the asked thickness."""
    text = open(os.path.join(case, "log.snappyHexMesh")).read()
    m = re.compile(r"(?m)^wall\s+\d+\s+([0-9.]+)\s+[0-9.eE+-]+\s+([0-9.]+)").search(
        text, text.rfind("overall thickness") + 1)
    if not m:
        raise RuntimeError("snappyHexMesh added no wall layers in " + case)
    return float(m.group(1)), float(m.group(2))


def snappy_tube(case, stl, z0, z1, half_width, h, location_z, layers, regions=()):
    """snappyHexMesh on a tube along z whose wall is constant/triSurface/`stl`
    (mm): a background block of h mm cubes from z0 to z1 (its end faces
    become the inlet and outlet patches), at least half_width + 2 h wide in x
    and y, castellated and snapped to the STL, each region of `regions`
    ((level, za, zb, radius): a cylinder along z refined to that level)
    refined inside, then `layers` wall layers (write_snappy_dict); then
    scaled to metres. The case's system/ must hold the rest (controlDict,
    schemes, solution). Returns the seconds taken and snappyHexMesh's layer
    figures: the wall layers on average and the percentage of the asked
    thickness."""
    nxy, nz = 2 * int(math.ceil((half_width + 2 * h) / h)), int(round((z1 - z0) / h))
    e = nxy * h / 2
    write_block_mesh_dict(case, (-e, -e, z0), (e, e, z1), (nxy, nxy, nz),
                          " inlet { type patch; faces ( (0 3 2 1) ); } outlet { type patch; faces ( (4 5 6 7) ); }\n"
                          "  sides { type patch; faces ( (0 1 5 4) (2 3 7 6) (1 2 6 5) (0 4 7 3) ); } ")
    geometry = "  %s { type triSurfaceMesh; name wall; }\n" % stl
    geometry += "".join("  region%d { type searchableCylinder; point1 (0 0 %.9g); point2 (0 0 %.9g); radius %.9g; }\n"
                        % (i, za, zb, r) for i, (_, za, zb, r) in enumerate(regions))
    refinement = "".join("    region%d { mode inside; levels ((1e15 %d)); }\n" % (i, level)
                         for i, (level, _, _, _) in enumerate(regions))
    write_snappy_dict(case, geometry, " wall { level (0 0); patchInfo { type wall; } } ", refinement,
                      (0.0123, 0.0234, location_z), layers)
    result = run_snappy(case)
    # The block's sides lie outside the tube: snappyHexMesh drops their
    # emptied patch, leaving the three the template's fields name.
    boundary = open(os.path.join(case, "constant", "polyMesh", "boundary")).read()
    if re.search(r"\n\s*sides\s*\{", boundary):
        raise RuntimeError("faces of the block's sides are left after snappyHexMesh in " + case)
    return result


# ---------------------------------------------------------------- the page

# docs/validation.md holds the tube page (tube_validation.py writes all of it)
# and sections other harnesses generate between these markers, kept when the
# tube harness rewrites the page.
CURVED_BEGIN = "<!-- curved_validation.py: begin (generated, do not edit) -->"
CURVED_END = "<!-- curved_validation.py: end -->"


def generated_section(text, begin=CURVED_BEGIN, end=CURVED_END):
    """The marked section of `text` (markers included), or ''."""
    i = text.find(begin)
    j = text.find(end, i + 1) if i >= 0 else -1
    if i < 0 or j < 0:
        return ""
    return text[i:j + len(end)]


# Any harness's section: "<!-- NAME: begin (generated, do not edit) -->"
# to "<!-- NAME: end -->" (curved_validation.py, multiscale_validation.py
# stepped and tree).
MARKED_SECTION = re.compile(r"<!-- ([^:>]+): begin \(generated, do not edit\) -->.*?<!-- \1: end -->", re.S)


def write_page(doc, text):
    """Writes `text` to `doc`, keeping each marked section the old file had
    and `text` has not, in their order, after it."""
    old = open(doc).read() if os.path.exists(doc) else ""
    have = {m.group(1) for m in MARKED_SECTION.finditer(text)}
    for m in MARKED_SECTION.finditer(old):
        if m.group(1) not in have:
            text = text.rstrip("\n") + "\n\n" + m.group(0) + "\n"
    with open(doc, "w") as f:
        f.write(text)


def replace_section(doc, section, begin=CURVED_BEGIN, end=CURVED_END):
    """Puts `section` (with its markers) in place of the marked section of
    `doc`, or appends it; the rest of the page stays as it is."""
    text = open(doc).read() if os.path.exists(doc) else ""
    old = generated_section(text, begin, end)
    if old:
        text = text.replace(old, section)
    else:
        text = text.rstrip("\n") + "\n\n" + section + "\n"
    with open(doc, "w") as f:
        f.write(text)
