#!/usr/bin/env python3
"""checkMesh's checks, default and all, on scalemesh's and snappyHexMesh's
meshes of the same surfaces.

For each sample case of cases/ (or those named) the case directory is copied
into a scratch directory (its input paths made absolute, `surface.msh` added
to its surface outputs) and meshed by `scalemesh run` with the case's own
settings (the default prism layers unless the case chooses otherwise:
aorta_mask chooses "delaunay"). checkMesh then runs on its polyMesh twice:
with the default checks and with `-allGeometry -allTopology`; a run's
failed checks are its lines starting with `***` and its closing
"Failed N mesh checks." (or "Mesh OK.").

snappyHexMesh then meshes the same surface: scalemesh's surface.msh (the
boundary of its mesh, in mm, each physical surface a patch: wall and the
openings' caps) written as an ASCII STL with one solid per patch and named
after the polyMesh's patches, the wall a `wall`, each cap a `patch`. A
background block of h mm cubes 2 h larger than the surface's bounding box on
every side (its faces end up outside and are dropped), castellated at level
0 and snapped to the STL, then 3 wall layers with tube_validation.py's
snappyHexMesh settings (common.write_snappy_dict), scaled to metres; the
locationInMesh is the centroid of scalemesh's tet with the largest inscribed
sphere (one per disconnected region of scalemesh's mesh, as
locationsInMesh: twin_tubes). h is chosen so that the estimate V / h^3 + 3 A_wall / h^2 (the cubes
inside the lumen and 3 layers on the wall) equals scalemesh's cell count.
The same two checkMesh runs follow.

`cylinder-M<M>` (--cylinder M ...) is tube_validation.py's `--surface
cylinder` case: scalemesh on the exact cylinder STL (scalemesh_case), and
its snappyHexMesh peer (snappy_case, the block's end faces the inlet and
outlet), h chosen by the same estimate from the cylinder's volume and wall.
Each also as a control, "cylinder-M<M>, snappyHexMesh on scalemesh's
surface": the same scalemesh case run again writing surface.msh, and
snappyHexMesh given that surface as on the sample cases.

Results go into validation/prisms/all-checks.json (merged with what it
holds, by case), one Markdown row per case printed.

    /usr/bin/python3 validation/all_checks.py [--scalemesh build/src/cli/scalemesh] [--cylinder 7 10] [case ...]
"""

import argparse
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import (REPO, log, read_polymesh, run, run_snappy, snappy_layers,  # noqa: E402
                    write_block_mesh_dict, write_snappy_dict)
from prism_layers import copy_case  # noqa: E402
from tube_validation import TUBE_HALF, TUBE_R, case_from_template, scalemesh_case, snappy_case  # noqa: E402

LAYERS = 3                        # snappyHexMesh's wall layers, as tube_validation.py's peer
RETRY_SECONDS = 90                # a snappyHexMesh run this quick is redone once when its cells miss by 2 times
RESULTS = os.path.join(REPO, "validation", "prisms", "all-checks.json")


# ---------------------------------------------------------------- checkMesh

def check_mesh(case, all_checks):
    """checkMesh on the case (default checks, or -allGeometry -allTopology):
    its cells, the failed-check count it states and its `***` lines."""
    cmd = ["checkMesh", "-case", "."] + (["-allGeometry", "-allTopology"] if all_checks else [])
    logname = "log.checkMesh-all" if all_checks else "log.checkMesh"
    try:
        text = run(cmd, case, logname)
        code = 0
    except RuntimeError:          # the log holds the output whatever the exit code
        text = open(os.path.join(case, logname)).read()
        code = 1
    m = re.search(r"(?m)^\s*cells:\s+(\d+)", text)
    failed = re.search(r"(?m)^\s*Failed (\d+) mesh checks\.", text)
    stars = [line.strip() for line in text.splitlines() if line.strip().startswith("***")]
    return {"cells": int(m.group(1)) if m else None,
            "mesh_ok": "Mesh OK." in text,
            # None: checkMesh ended without its verdict (it crashed), which
            # counts as neither a pass nor a number of failed checks.
            "failed": int(failed.group(1)) if failed else (0 if "Mesh OK." in text else None),
            "failed_checks": stars,
            "exit_code": code}


def cell_kinds(case):
    """The polyMesh's cells by shape: tet, prism, pyramid, hex, or
    "polyhedron F/P" (F faces, P points)."""
    _, faces, owner, neighbour = read_polymesh(case)
    nfaces, points = {}, {}
    for i, face in enumerate(faces):
        for cell in (owner[i], neighbour[i]) if i < len(neighbour) else (owner[i],):
            nfaces[cell] = nfaces.get(cell, 0) + 1
            points.setdefault(cell, set()).update(face)
    names = {(4, 4): "tet", (5, 6): "prism", (5, 5): "pyramid", (6, 8): "hex"}
    return {c: names.get((n, len(points[c])), "polyhedron %d/%d" % (n, len(points[c]))) for c, n in nfaces.items()}


def failed_cells(case):
    """The cell sets checkMesh -allGeometry -allTopology wrote (concaveCells,
    underdeterminedCells, ...; twoInternalFacesCells is a warning's, not a
    failed check's): per set, its cells counted by shape."""
    sets = os.path.join(case, "constant", "polyMesh", "sets")
    if not os.path.isdir(sets):
        return {}
    kinds, out = None, {}
    for name in sorted(os.listdir(sets)):
        path = os.path.join(sets, name)
        if "cellSet" not in open(path).read(2000) or name.startswith("region"):
            continue   # region0, region1, ...: the mesh's disconnected regions, no check's
        kinds = kinds or cell_kinds(case)
        counts = {}
        text = re.sub(r"//[^\n]*", "", open(path).read())
        m = re.search(r"(\d+)\s*\(([^)]*)\)", text[text.index("}") + 1:])
        for cell in m.group(2).split():
            kind = kinds[int(cell)]
            counts[kind] = counts.get(kind, 0) + 1
        out[name] = counts
    return out


def check_both(case):
    result = {"default": check_mesh(case, False), "all": check_mesh(case, True)}
    result["cell_shapes"] = {}
    for kind in cell_kinds(case).values():
        result["cell_shapes"][kind] = result["cell_shapes"].get(kind, 0) + 1
    result["failed_cell_sets"] = failed_cells(case)
    return result


# ---------------------------------------------------------------- surfaces

def patch_names(case):
    """The polyMesh's patches in order: (name, type, nFaces)."""
    text = open(os.path.join(case, "constant", "polyMesh", "boundary")).read()
    out = []
    for m in re.finditer(r"\n\s*(\w+)\s*\{([^}]*)\}", text):
        body = m.group(2)
        if "nFaces" in body:
            out.append((m.group(1), re.search(r"type\s+(\w+);", body).group(1),
                        int(re.search(r"nFaces\s+(\d+)", body).group(1))))
    return out


def surface_triangles(case):
    """scalemesh's surface.msh: per patch of the polyMesh (in order, matched
    to the physical surfaces by order and face count), its type and its
    triangles as an (n, 3, 3) array in mm."""
    import meshio
    import numpy as np

    mesh = meshio.read(os.path.join(case, "surface.msh"))
    by_tag = {}
    for block, tags in zip(mesh.cells, mesh.cell_data["gmsh:physical"]):
        if block.type != "triangle":
            continue
        for tag in np.unique(tags):
            by_tag.setdefault(int(tag), []).append(block.data[tags == tag])
    groups = [np.concatenate(by_tag[t]) for t in sorted(by_tag)]
    patches = patch_names(case)
    if [len(g) for g in groups] != [n for _, _, n in patches]:
        raise RuntimeError("surface.msh's physical surfaces (%s faces) are not the polyMesh's patches (%s)"
                           % ([len(g) for g in groups], patches))
    return [(name, kind, mesh.points[g]) for (name, kind, _), g in zip(patches, groups)]


def write_patch_stl(path, patches):
    """An ASCII STL, one solid per patch."""
    import numpy as np

    with open(path, "w") as f:
        for name, _, tris in patches:
            f.write("solid %s\n" % name)
            normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
            normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
            for n, t in zip(normals, tris):
                f.write("facet normal %.9g %.9g %.9g\nouter loop\n" % tuple(n))
                for p in t:
                    f.write("vertex %.9g %.9g %.9g\n" % tuple(p))
                f.write("endloop\nendfacet\n")
            f.write("endsolid %s\n" % name)


def volume_and_wall(patches):
    """The closed surface's enclosed volume (mm^3) and its wall area (mm^2)."""
    import numpy as np

    tris = np.concatenate([t for _, _, t in patches])
    volume = abs(np.einsum("ij,ij->i", tris[:, 0], np.cross(tris[:, 1], tris[:, 2])).sum()) / 6
    wall = sum(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum()
               for _, kind, t in patches if kind == "wall")
    return volume, wall


def deep_points(case):
    """Per connected region of scalemesh's tets (mesh.msh, mm; tets joined
    by shared nodes), the centroid of its tet with the largest inscribed
    sphere: a point well inside the lumen."""
    import gmsh  # Debian python3-gmsh (meshio refuses the point data of scalemesh's mesh.msh)
    import numpy as np

    gmsh.initialize(["gmsh", "-nopopup"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(os.path.join(case, "mesh.msh"))
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, nodes = gmsh.model.mesh.getElementsByType(4)
    finally:
        gmsh.finalize()
    index = np.zeros(int(tags.max()) + 1, dtype=int)
    index[tags.astype(int)] = np.arange(len(tags))
    p = coords.reshape(-1, 3)[index[nodes.astype(int)].reshape(-1, 4)]
    volume = np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6
    area = sum(0.5 * np.linalg.norm(np.cross(p[:, b] - p[:, a], p[:, c] - p[:, a]), axis=1)
               for a, b, c in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)))
    inradius = 3 * volume / area
    tets = index[nodes.astype(int)].reshape(-1, 4)
    label = np.arange(len(tags))
    while True:   # each node labelled with the least node index of its region
        low = label[tets].min(axis=1)
        new = label.copy()
        np.minimum.at(new, tets.ravel(), np.repeat(low, 4))
        if np.array_equal(new, label):
            break
        label = new
    region = label[tets[:, 0]]
    return [tuple(p[np.flatnonzero(region == r)[np.argmax(inradius[region == r])]].mean(axis=0))
            for r in np.unique(region)]


def cell_size(volume, wall, cells):
    """h (mm) with volume / h^3 + LAYERS * wall / h^2 = cells."""
    lo, hi = 1e-3, 1e3
    for _ in range(200):
        h = math.sqrt(lo * hi)
        if volume / h ** 3 + LAYERS * wall / h ** 2 > cells:
            lo = h
        else:
            hi = h
    return h


def snappy_surface(case, scalemesh_dir, cells, scale=1.0):
    """snappyHexMesh on scalemesh's surface (module docstring) in `case`,
    about `cells` cells, its h the estimate's times `scale`. Returns h (mm),
    the seconds taken, the wall layers on average and the percentage of the
    asked thickness."""
    import numpy as np

    case_from_template(case, scalemesh_dir)
    patches = surface_triangles(scalemesh_dir)
    os.makedirs(os.path.join(case, "constant", "triSurface"))
    write_patch_stl(os.path.join(case, "constant", "triSurface", "surface.stl"), patches)
    volume, wall = volume_and_wall(patches)
    h = scale * cell_size(volume, wall, cells)
    points = np.concatenate([t.reshape(-1, 3) for _, _, t in patches])
    lo, hi = points.min(axis=0) - 2 * h, points.max(axis=0) + 2 * h
    n = np.ceil((hi - lo) / h).astype(int)
    hi = lo + n * h
    write_block_mesh_dict(case, lo, hi, n, " box { type patch; faces ( (0 3 2 1) (4 5 6 7) (0 1 5 4) (2 3 7 6) "
                          "(1 2 6 5) (0 4 7 3) ); } ")
    names = "".join("    %s { name %s; }\n" % (name, name) for name, _, _ in patches)
    geometry = "  surface.stl { type triSurfaceMesh; name surface;\n  regions {\n%s  } }\n" % names
    surfaces = " surface { level (0 0); regions {\n%s } } " % "".join(
        "    %s { level (0 0); patchInfo { type %s; } }\n" % (name, "wall" if kind == "wall" else "patch")
        for name, kind, _ in patches)
    points = deep_points(scalemesh_dir)
    write_snappy_dict(case, geometry, surfaces, "", points[0] if len(points) == 1 else points, LAYERS)
    seconds, layers_made, thickness = run_snappy(case)
    return h, seconds, layers_made, thickness


# ---------------------------------------------------------------- cases

def one_case(name, scratch, binary):
    """scalemesh and snappyHexMesh on one sample case: a results dict."""
    result = {"case": name}
    sm = os.path.join(scratch, name, "scalemesh")
    os.makedirs(os.path.dirname(sm), exist_ok=True)
    toml = copy_case(os.path.join(REPO, "cases", name), sm)
    text = open(toml).read()
    text, k = re.subn(r"(?m)^(\s*surface\s*=\s*)\[[^\]]*\]", r'\1["surface.msh"]', text)
    if not k:
        text = re.sub(r"(?m)^\[output\]\s*$", '[output]\nsurface = ["surface.msh"]', text) \
            if re.search(r"(?m)^\[output\]\s*$", text) else text + '\n[output]\nsurface = ["surface.msh"]\n'
    open(toml, "w").write(text)
    t = time.time()
    try:
        run([binary, "run", sm, "-q"], sm, "log.scalemesh-run")
    except RuntimeError as e:
        result["scalemesh"] = {"error": str(e)[-2000:]}
        return result
    report = json.load(open(os.path.join(sm, "report.json")))
    result["scalemesh"] = {"seconds": round(time.time() - t, 1),
                           "layers_built": report.get("volume", {}).get("layers_built")}
    result["scalemesh"].update(check_both(sm))
    log("%s: scalemesh %s cells, failed checks %d default, %d all"
        % (name, result["scalemesh"]["default"]["cells"], result["scalemesh"]["default"]["failed"],
           result["scalemesh"]["all"]["failed"]))
    result["snappy"] = snappy_on_surface(name, os.path.join(scratch, name, "snappy"), sm,
                                         result["scalemesh"]["default"]["cells"])
    return result


def snappy_on_surface(name, sn, sm, target):
    """snappyHexMesh in `sn` on the surface of scalemesh's case `sm`, about
    `target` cells (one retry when the estimate misses by 2 times and the
    run was quick): its results dict."""
    scale, tries = 1.0, []
    while True:
        if os.path.exists(sn):
            shutil.rmtree(sn)
        try:
            h, seconds, layers_made, thickness = snappy_surface(sn, sm, target, scale)
        except Exception as e:  # noqa: BLE001 -- recorded, the next case runs
            log("%s: snappyHexMesh failed: %s" % (name, str(e)[-500:]))
            return {"error": str(e)[-2000:], "earlier_tries": tries}
        result = {"h_mm": round(h, 4), "seconds": round(seconds, 1), "wall_layers_mean": layers_made,
                  "thickness_percent": thickness, "patches": [p for p, _, _ in patch_names(sn)]}
        result.update(check_both(sn))
        cells = result["default"]["cells"]
        # One retry when the estimate missed by more than a factor of 2 and
        # the run was quick: h scaled by the cube root of the miss.
        if tries or cells is None or 0.5 <= cells / target <= 2 or seconds > RETRY_SECONDS:
            break
        tries.append({"h_mm": round(h, 4), "cells": cells, "seconds": round(seconds, 1)})
        scale *= (cells / target) ** (1 / 3)
    result["earlier_tries"] = tries
    log("%s: snappyHexMesh h %.3g mm, %s cells, failed checks %d default, %d all, %.0f s"
        % (name, h, cells, result["default"]["failed"], result["all"]["failed"], seconds))
    return result


def cylinder_case(M, scratch, binary):
    """tube_validation.py's --surface cylinder case at M and its
    snappyHexMesh peer."""
    name = "cylinder-M%g" % M
    result = {"case": name}
    sm = os.path.join(scratch, name, "scalemesh")
    os.makedirs(os.path.dirname(sm), exist_ok=True)
    seconds = scalemesh_case(binary, M, sm, "cylinder")
    report = json.load(open(os.path.join(sm, "report.json")))
    result["scalemesh"] = {"seconds": round(seconds, 1),
                           "layers_built": report.get("volume", {}).get("layers_built")}
    result["scalemesh"].update(check_both(sm))
    cells = result["scalemesh"]["default"]["cells"]
    length = 2 * TUBE_HALF
    h = cell_size(math.pi * TUBE_R ** 2 * length, 2 * math.pi * TUBE_R * length, cells)
    sn = os.path.join(scratch, name, "snappy")
    try:
        seconds = snappy_case(h, sn, sm, LAYERS)
    except Exception as e:  # noqa: BLE001
        result["snappy"] = {"h_mm": round(h, 4), "error": str(e)[-2000:]}
        return result
    layers_made, thickness = snappy_layers(sn)
    result["snappy"] = {"h_mm": round(h, 4), "seconds": round(seconds, 1), "wall_layers_mean": layers_made,
                        "thickness_percent": thickness, "patches": [p for p, _, _ in patch_names(sn)]}
    result["snappy"].update(check_both(sn))
    log("%s: scalemesh %d cells (%d / %d failed), snappyHexMesh h %.3g mm %s cells (%d / %d failed)"
        % (name, cells, result["scalemesh"]["default"]["failed"], result["scalemesh"]["all"]["failed"], h,
           result["snappy"]["default"]["cells"], result["snappy"]["default"]["failed"],
           result["snappy"]["all"]["failed"]))
    return result


def cylinder_surface_case(M, scratch, binary):
    """The control: the cylinder case at M run again writing surface.msh,
    and snappyHexMesh given that surface (scalemesh's boundary, caps as
    inlet and outlet) as on the sample cases, in place of the peer's fine
    STL of the cylinder's side."""
    name = "cylinder-M%g, snappyHexMesh on scalemesh's surface" % M
    result = {"case": name}
    source = os.path.join(scratch, "cylinder-M%g" % M, "scalemesh")
    sm = os.path.join(scratch, "cylinder-M%g" % M, "scalemesh-surface")
    os.makedirs(sm, exist_ok=True)
    for file in ("scalemesh.toml", "cylinder.stl"):
        shutil.copy(os.path.join(source, file), sm)
    toml = os.path.join(sm, "scalemesh.toml")
    text, k = re.subn(r"(?m)^surface = \[\]", 'surface = ["surface.msh"]', open(toml).read())
    if k != 1:
        raise RuntimeError("no `surface = []` in " + toml)
    open(toml, "w").write(text)
    t = time.time()
    run([binary, "run", sm, "-q"], sm, "log.scalemesh-run")
    report = json.load(open(os.path.join(sm, "report.json")))
    result["scalemesh"] = {"seconds": round(time.time() - t, 1),
                           "layers_built": report.get("volume", {}).get("layers_built")}
    result["scalemesh"].update(check_both(sm))
    result["snappy"] = snappy_on_surface(name, os.path.join(scratch, "cylinder-M%g" % M, "snappy-surface"), sm,
                                         result["scalemesh"]["default"]["cells"])
    return result


CHECK_NAMES = {"Cells with small determinant": "determinant", "Concave cells (using face planes)": "concave",
               "Faces with small interpolation weight": "weight", "Error in face tets": "face tets",
               "Max skewness": "skewness"}


def checks_text(m):
    """A run's failed checks (all), each with the cells or faces it names."""
    out = []
    for line in m["all"]["failed_checks"]:
        text = line.lstrip("*").strip()
        name = next((v for k, v in CHECK_NAMES.items() if text.startswith(k)), text)
        n = re.search(r"number of cells: (\d+)", text)
        if n:
            out.append("%s %s" % (name, n.group(1)))
            continue
        n = re.search(r"number of faces: (\d+)", text) or re.search(r"(\d+) (?:highly skew )?faces", text)
        out.append("%s %s face%s" % (name, n.group(1), "" if n.group(1) == "1" else "s") if n else name)
    return ", ".join(out) or "-"


def row(r):
    cols = [r["case"].replace(", snappyHexMesh on", ", control: snappyHexMesh on")]
    for mesher in ("scalemesh", "snappy"):
        m = r.get(mesher)
        if not m:
            cols += ["not run", "", ""]
        elif "error" in m:
            cols += ["failed: " + m["error"].strip().splitlines()[0][:80], "", ""]
        else:
            if mesher == "scalemesh":
                note = {"prisms": "prisms", "delaunay": "Delaunay"}.get(m.get("layers_built"), "?")
            else:
                note = "%.3g mm, %.2f" % (m["h_mm"], m.get("wall_layers_mean", float("nan")))
            count = lambda n: "error" if n is None else "%d" % n  # noqa: E731
            cells = m["default"]["cells"]
            cols += ["{:,} ({})".format(cells, note) if cells is not None else "? (%s)" % note,
                     "%s / %s" % (count(m["default"]["failed"]), count(m["all"]["failed"])), checks_text(m)]
    sm, sn = r.get("scalemesh", {}), r.get("snappy", {})
    known = "all" in sm and "all" in sn and sm["all"]["failed"] is not None and sn["all"]["failed"] is not None
    cols.append(("yes" if sm["all"]["failed"] <= sn["all"]["failed"] else "no") if known else "-")
    return "| " + " | ".join(cols) + " |"


HEADER = ("| case | scalemesh: cells (layers) | failed: default / all | its failed checks (all) "
          "| snappyHexMesh: cells (h, wall layers) | failed: default / all | its failed checks (all) "
          "| all: scalemesh <= snappyHexMesh |\n|---|---|---|---|---|---|---|---|")


def table(results):
    """The Markdown table: the cylinder rows first (M ascending), then the
    sample cases."""
    def key(r):
        m = re.match(r"cylinder-M([0-9.]+)", r["case"])
        return (0, float(m.group(1)), r["case"]) if m else (1, 0, r["case"])
    return HEADER + "\n" + "\n".join(row(r) for r in sorted(results, key=key))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cases", nargs="*", help="case names under cases/ (default: every case)")
    ap.add_argument("--scalemesh", default=os.path.join(REPO, "build", "src", "cli", "scalemesh"))
    ap.add_argument("--cylinder", type=float, nargs="*", default=[7, 10],
                    help="M of tube_validation.py's --surface cylinder case (none to leave it out)")
    ap.add_argument("--out", default=RESULTS)
    ap.add_argument("--keep", help="a directory to keep the meshes in (default: a temporary one, removed)")
    ap.add_argument("--table", action="store_true", help="print the table of --out's results, running nothing")
    args = ap.parse_args()
    if args.table:
        print(table(json.load(open(args.out))))
        return 0
    binary = os.path.abspath(args.scalemesh)
    names = args.cases or sorted(d for d in os.listdir(os.path.join(REPO, "cases"))
                                 if os.path.isfile(os.path.join(REPO, "cases", d, "scalemesh.toml")))
    results = {}
    if os.path.exists(args.out):
        results = {r["case"]: r for r in json.load(open(args.out))}

    def save(r):
        results[r["case"]] = r
        os.makedirs(os.path.dirname(args.out), exist_ok=True)
        with open(args.out, "w") as f:
            json.dump(sorted(results.values(), key=lambda x: x["case"]), f, indent=1)

    scratch = args.keep or tempfile.mkdtemp(prefix="all-checks-")
    os.makedirs(scratch, exist_ok=True)
    done = []
    try:
        for M in args.cylinder:
            done.append(cylinder_case(M, scratch, binary))
            save(done[-1])
            done.append(cylinder_surface_case(M, scratch, binary))
            save(done[-1])
        for name in names:
            done.append(one_case(name, scratch, binary))
            save(done[-1])
    finally:
        if not args.keep:
            shutil.rmtree(scratch, ignore_errors=True)
    print(table(done))
    return 0


if __name__ == "__main__":
    sys.exit(main())
