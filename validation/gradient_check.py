#!/usr/bin/env python3
"""Consistency check of OpenFOAM's cell gradient schemes on a mesh.

For an exactly linear field, f = z say (cell values the cell-centre z,
boundary values the face-centre z), a consistent gradient scheme gives
grad f = (0, 0, 1) in every cell. This script computes OpenFOAM's grad(f)
(`postProcess -func 'grad(f)'`) with each of the given gradSchemes on a copy
of each case's constant/polyMesh and prints, over the cells, the mean and the
maximum of |grad f - (0, 0, 1)|, the fraction of cells where it exceeds 1%
and 10%, and its mean over the cells with and without a boundary face.
`Gauss linear` is not consistent on skewed cells: its linear face
interpolation is not at the face centroid (Syrakos et al. 2017, "A critical
analysis of some popular methods for the discretisation of the gradient
operator in finite volume methods", arXiv 1606.05556).

    /usr/bin/python3 validation/gradient_check.py CASE [CASE ...] [--axis z] \\
        [--schemes 'Gauss linear' 'Gauss pointLinear' pointCellsLeastSquares leastSquares] \\
        [--workdir /tmp/scalemesh-gradient-check]

CASE is any OpenFOAM case with an ASCII constant/polyMesh (as scalemesh and
gmshToFoam write it). The meshes of validation/notes.md, scalemesh M = 14 and
Gmsh h = 0.55 mm, are built by the tube harness's helpers (the Gmsh case takes
system/ from the scalemesh case); from the repository's root:

    /usr/bin/python3 -c "import os, sys; sys.dont_write_bytecode = True; sys.path.insert(0, 'validation'); \\
        import tube_validation as t; \\
        t.scalemesh_case(os.path.abspath('build/src/cli/scalemesh'), 14, '/tmp/gradcheck/scalemesh-M14'); \\
        t.gmsh_case(0.55, '/tmp/gradcheck/gmsh-h0.55', '/tmp/gradcheck/scalemesh-M14')"
    /usr/bin/python3 validation/gradient_check.py /tmp/gradcheck/scalemesh-M14 /tmp/gradcheck/gmsh-h0.55

Needs: python3 with numpy, OpenFOAM v1912 (postProcess); the Gmsh mesh above
also the Gmsh Python module (Debian python3-gmsh).
"""

import argparse
import os
import re
import shutil
import sys

import numpy as np

sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import log, run, internal_field, patch_field, foam_list_lines  # noqa: E402

HEADER = "FoamFile { version 2.0; format ascii; class %s; object %s; }\n"
CONTROL = """application none; startFrom startTime; startTime 0; stopAt endTime; endTime 0;
deltaT 1; writeControl timeStep; writeInterval 1; writeFormat ascii; writePrecision 15;
writeCompression off; timeFormat general; timePrecision 6; runTimeModifiable false;
"""
SCHEMES = """ddtSchemes { default steadyState; }
gradSchemes { default %s; }
divSchemes { default none; }
laplacianSchemes { default none; }
interpolationSchemes { default linear; }
snGradSchemes { default corrected; }
"""


def prepare(case, work, axis):
    """A scratch case with the case's polyMesh and 0/f = the coordinate
    `axis` (0, 1, 2). Returns a boolean array over the cells, True for the
    cells with a boundary face."""
    if os.path.exists(work):
        shutil.rmtree(work)
    os.makedirs(os.path.join(work, "system"))
    os.makedirs(os.path.join(work, "0"))
    poly = os.path.join(work, "constant", "polyMesh")
    shutil.copytree(os.path.join(case, "constant", "polyMesh"), poly)
    for name, body in (("controlDict", CONTROL), ("fvSchemes", SCHEMES % "Gauss linear"), ("fvSolution", "")):
        with open(os.path.join(work, "system", name), "w") as f:
            f.write(HEADER % ("dictionary", name) + body)
    run(["postProcess", "-case", ".", "-time", "0", "-func", "writeCellCentres"], work, "log.cellCentres")
    centres = os.path.join(work, "0", "C")
    cells = internal_field(centres, 3)

    def values(points):
        return "nonuniform List<scalar> %d\n(\n%s\n)" % (len(points), "\n".join("%.15g" % p[axis] for p in points))

    out = [HEADER % ("volScalarField", "f"), "dimensions [0 1 0 0 0 0 0];\n",
           "internalField %s;\n" % values(cells), "boundaryField\n{\n"]
    # The patches: name, type, nFaces, startFace, as polyMesh/boundary lists them.
    patches = re.findall(r"\n\s*(\w+)\s*\{[^}]*?type\s+(\w+);[^}]*?nFaces\s+(\d+);\s*startFace\s+(\d+);",
                         open(os.path.join(poly, "boundary")).read())
    for name, kind, n, _ in patches:
        if kind == "empty":
            out.append("    %s { type empty; }\n" % name)
        else:
            faces = patch_field(centres, name, 3) if int(n) else []
            out.append("    %s { type fixedValue; value %s; }\n" % (name, values(faces)))
    out.append("}\n")
    with open(os.path.join(work, "0", "f"), "w") as f:
        f.write("".join(out))

    owner = [int(v) for v in foam_list_lines(os.path.join(poly, "owner"))]
    at_boundary = np.zeros(len(cells), bool)
    at_boundary[owner[min(int(p[3]) for p in patches):]] = True
    return at_boundary


def gradient_error(work, scheme, axis):
    """|grad f - e_axis| per cell with gradSchemes `default scheme`."""
    with open(os.path.join(work, "system", "fvSchemes"), "w") as f:
        f.write(HEADER % ("dictionary", "fvSchemes") + SCHEMES % scheme)
    run(["postProcess", "-case", ".", "-time", "0", "-func", "grad(f)"], work, "log.grad")
    g = np.array(internal_field(os.path.join(work, "0", "grad(f)"), 3))
    return np.linalg.norm(g - np.eye(3)[axis], axis=1)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cases", nargs="+", help="OpenFOAM cases with a constant/polyMesh")
    ap.add_argument("--axis", choices="xyz", default="z", help="f is this coordinate (default z, the tube's axis)")
    ap.add_argument("--schemes", nargs="+",
                    default=["Gauss linear", "Gauss pointLinear", "pointCellsLeastSquares", "leastSquares"])
    ap.add_argument("--workdir", default="/tmp/scalemesh-gradient-check")
    args = ap.parse_args()
    axis = "xyz".index(args.axis)
    log("f = %s; error = |grad f - e_%s| over the cells" % (args.axis, args.axis))
    log("| case | cells | gradient scheme | mean error | max error | cells > 1% | cells > 10% "
        "| mean, cells with a boundary face | mean, other cells |")
    log("|---|---|---|---|---|---|---|---|---|")
    for case in args.cases:
        name = os.path.basename(os.path.normpath(case))
        work = os.path.join(args.workdir, name)
        at_boundary = prepare(case, work, axis)
        for scheme in args.schemes:
            e = gradient_error(work, scheme, axis)
            log("| %s | %d | %s | %.4g%% | %.4g%% | %.1f%% | %.1f%% | %.4g%% (%d cells) | %.4g%% |" % (
                name, len(e), scheme, 100 * e.mean(), 100 * e.max(), 100 * np.mean(e > 0.01),
                100 * np.mean(e > 0.1), 100 * e[at_boundary].mean(), at_boundary.sum(), 100 * e[~at_boundary].mean()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
