#!/usr/bin/python3
"""The layer and quality figures of every sample case, as docs/method.md shows them.

Runs `scalemesh -q run --strict --threads 2` on a copy of each case under
cases/ (aorta_surface_m16 is the aorta at M = 16), and of the tube and the
torus with the paper's first layer and with the paper's Delaunay layers, reads
report.json, runs OpenFOAM's checkMesh, and prints a markdown table (the worst
aspect ratio and smallest dihedral angle of the cells the floors judge: with
prism layers the tets written as cells of their own); with --doc FILE it replaces the table between the
markers `<!-- layer figures -->` and `<!-- end layer figures -->` in FILE.

    /usr/bin/python3 bench/layer_figures.py --scalemesh build/src/cli/scalemesh --doc docs/method.md
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def with_keys(text, section, keys):
    """The case file with `keys` set in [section] (added when missing)."""
    for key, value in keys.items():
        line = f"{key} = {value}"
        if re.search(rf"^\[{section}\]\s*$", text, re.M):
            if re.search(rf"^{key}\s*=.*$", text, re.M):
                text = re.sub(rf"^{key}\s*=.*$", line, text, count=1, flags=re.M)
            else:
                text = re.sub(rf"^\[{section}\]\s*$", f"[{section}]\n{line}", text, count=1, flags=re.M)
        else:
            at = text.find("[[openings]]")
            block = f"[{section}]\n{line}\n\n"
            text = text[:at] + block + text[at:] if at >= 0 else text + "\n" + block
    return text


def run_case(scalemesh, work, name, label, edits):
    src = os.path.join(ROOT, "cases", name)
    dst = os.path.join(work, label)
    os.makedirs(dst)
    text = open(os.path.join(src, "scalemesh.toml")).read()
    # An input file named relative to the case resolves against the original.
    text = re.sub(r'file = "([^"/][^"]*)"',
                  lambda m: 'file = "' + os.path.normpath(os.path.join(src, m.group(1))) + '"', text)
    for section, keys in edits.items():
        text = with_keys(text, section, keys)
    open(os.path.join(dst, "scalemesh.toml"), "w").write(text)
    run = subprocess.run([scalemesh, "-q", "run", "--strict", "--threads", "2", dst], capture_output=True, text=True)
    if run.returncode not in (0, 6):
        sys.exit(f"{label}: scalemesh exited {run.returncode}: {run.stderr}")
    report = json.load(open(os.path.join(dst, "report.json")))
    env = dict(os.environ, WM_PROJECT_DIR="/usr/share/openfoam")
    check = subprocess.run(["checkMesh", "-case", dst], capture_output=True, text=True, env=env).stdout
    ortho = re.search(r"non-orthogonality Max: ([0-9.]+)", check)
    severe = re.search(r"severely non-orthogonal \(> 70 degrees\) faces: (\d+)", check)
    layers, volume, foam = report["layers"], report["volume"], report["openfoam"]
    quality = volume["quality_after_sliver_removal"]
    # The cells the floors judge: with prism layers written as prism cells
    # the tets written as cells of their own, else every tet.
    cells = foam.get("tet_cells_min_aspect_ratio") is not None
    return {
        "case": label,
        "M": report["parameters"]["M"],
        "owed": layers["eligible_wall_nodes"],
        "coverage": layers["coverage"],
        "mean": layers["mean_layers"],
        "stand_ins": layers["stand_ins"],
        "released": volume["dihedral_pass"].get("released_layer_points", 0),
        "anisotropy": volume["first_layer_anisotropy_median"],
        "tets": volume["tets"],
        "built": volume.get("layers_built", report["parameters"]["layers"]),
        "cells": foam["cells"],
        "prisms": foam["layer_prisms"],
        "intact": foam["intact_prism_share"],
        "worst_aspect": foam["tet_cells_min_aspect_ratio"] if cells else quality["min_aspect_ratio"],
        "min_dihedral": foam["tet_cells_min_dihedral_deg"] if cells else quality["min_dihedral_deg"],
        "non_ortho": float(ortho.group(1)) if ortho else float("nan"),
        "severe": int(severe.group(1)) if severe else 0,
        "mesh_ok": "\nMesh OK." in check,
        "warnings": len(report["warnings"]),
    }


def table(rows):
    out = ["| case | M | layers | wall nodes owed | all layers | mean layers | stand-ins | layer points released | "
           "anisotropy median | tets | OpenFOAM cells (layer prisms) | intact prisms | worst aspect ratio | "
           "min dihedral (deg) | checkMesh | max non-orth. (deg) | faces > 70 deg | warnings |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['case']} | {r['M']:g} | {r['built']} | {r['owed']} | {100 * r['coverage']:.2f}% | {r['mean']:.2f} | "
                   f"{r['stand_ins']} | {r['released']} | {r['anisotropy']:.2f} | {r['tets']} | {r['cells']} ({r['prisms']}) | "
                   f"{100 * r['intact']:.1f}% | "
                   f"{r['worst_aspect']:.4f} | "
                   f"{r['min_dihedral']:.2f} | {'Mesh OK' if r['mesh_ok'] else 'FAILED'} | {r['non_ortho']:.2f} | "
                   f"{r['severe']} | {r['warnings']} |")
    return "\n".join(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scalemesh", default=os.path.join(ROOT, "build/src/cli/scalemesh"))
    parser.add_argument("--doc", help="markdown file whose marked table is replaced")
    args = parser.parse_args()
    scalemesh = os.path.abspath(args.scalemesh)
    cases = sorted(d for d in os.listdir(os.path.join(ROOT, "cases"))
                   if os.path.exists(os.path.join(ROOT, "cases", d, "scalemesh.toml")))
    runs = [(c, c, {}) for c in cases]
    runs += [(c, f"{c}, first_layer = paper", {"volume": {"first_layer": '"paper"'}}) for c in ("tube", "torus")]
    runs += [(c, f"{c}, layers = delaunay", {"volume": {"layers": '"delaunay"'}}) for c in ("tube", "torus")]
    work = tempfile.mkdtemp(prefix="scalemesh-layer-figures-")
    try:
        rows = []
        for name, label, edits in runs:
            rows.append(run_case(scalemesh, work, name, label.replace(", ", "_").replace(" = ", "_").replace(" ", ""),
                                 edits))
            rows[-1]["case"] = label
            print(f"{label}: done", file=sys.stderr)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    text = table(rows)
    print(text)
    if args.doc:
        doc = open(args.doc).read()
        begin, end = "<!-- layer figures -->", "<!-- end layer figures -->"
        if begin not in doc or end not in doc:
            sys.exit(f"{args.doc} has no {begin} ... {end} markers")
        doc = doc[:doc.index(begin) + len(begin)] + "\n" + text + "\n" + doc[doc.index(end):]
        open(args.doc, "w").write(doc)


if __name__ == "__main__":
    main()
