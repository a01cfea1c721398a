#!/usr/bin/env python3
"""Each sample case meshed with [volume] layers = "prisms", then checked by checkMesh.

Copies every case directory of cases/ (or those named) into a scratch
directory, with its input file paths made absolute and `layers = "prisms"`
added to its [volume] section, runs `scalemesh run` and OpenFOAM's checkMesh on
it, and prints one Markdown row per case from its report.json: the share of
wall faces x layers written as single prism cells, the largest face
non-orthogonality OpenFOAM sees, the smallest dihedral angle of the tets
written as cells of their own, the layer account's coverage, the columns the
stack shortened, the columns holding all layers (of the wall nodes owed them)
with their height over Algorithm 4's, the tets joined to a neighbouring cell
and checkMesh's verdict. These are the figures of
docs/case-file.md's `layers` row.

    python3 validation/prism_layers.py [--scalemesh build/src/cli/scalemesh] [case ...]
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def copy_case(source, target):
    """Copies case directory `source` to `target`, its input file paths made
    absolute. Returns the path of the copy's scalemesh.toml."""
    shutil.copytree(source, target)
    path = os.path.join(target, "scalemesh.toml")
    with open(path) as f:
        text = f.read()

    def absolute(match):
        file = match.group(2)
        if not os.path.isabs(file):
            file = os.path.normpath(os.path.join(source, file))
        return f'{match.group(1)}"{file}"'

    text = re.sub(r'^(\s*file\s*=\s*)"([^"]*)"', absolute, text, flags=re.M)
    with open(path, "w") as f:
        f.write(text)
    return path


def prism_case(source, target):
    """Copies case directory `source` to `target` with layers = "prisms"."""
    path = copy_case(source, target)
    with open(path) as f:
        text = f.read()
    if re.search(r"^layers\s*=", text, flags=re.M):  # a case that chooses its layers
        text = re.sub(r"^layers\s*=.*$", 'layers = "prisms"', text, count=1, flags=re.M)
    elif re.search(r"^\[volume\]\s*$", text, flags=re.M):
        text = re.sub(r"^\[volume\]\s*$", '[volume]\nlayers = "prisms"', text, count=1, flags=re.M)
    else:
        text += '\n[volume]\nlayers = "prisms"\n'
    with open(path, "w") as f:
        f.write(text)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("cases", nargs="*", help="case names under cases/ (default: every case)")
    ap.add_argument("--scalemesh", default=os.path.join(REPO, "build", "src", "cli", "scalemesh"))
    args = ap.parse_args()
    names = args.cases or sorted(d for d in os.listdir(os.path.join(REPO, "cases"))
                                 if os.path.isfile(os.path.join(REPO, "cases", d, "scalemesh.toml")))
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    print("| case | intact prisms | max non-orthogonality (deg) | min dihedral of tet cells (deg) | layer coverage | "
          "shortened columns | whole columns, height (mean, min) | tets joined | checkMesh |")
    print("|---|---|---|---|---|---|---|---|---|")
    failed = False
    with tempfile.TemporaryDirectory(prefix="prism-layers-") as scratch:
        for name in names:
            case = os.path.join(scratch, name)
            prism_case(os.path.join(REPO, "cases", name), case)
            run = subprocess.run([args.scalemesh, "run", case, "-q"], capture_output=True, text=True)
            if run.returncode != 0:
                print(f"| {name} | run failed ({run.returncode}): {run.stderr.strip()} | | | | | | | |")
                failed = True
                continue
            check = subprocess.run(["checkMesh", "-case", case], capture_output=True, text=True, env=env)
            verdict = "Mesh OK" if "Mesh OK." in check.stdout else "failed"
            failed = failed or verdict != "Mesh OK"
            with open(os.path.join(case, "report.json")) as f:
                report = json.load(f)
            foam, layers, volume = report["openfoam"], report["layers"], report["volume"]
            if volume.get("layers_built", "prisms") != "prisms":
                # Given up for the paper's layers (report.json says why).
                print(f"| {name} | {100 * foam['intact_prism_share']:.1f}% (Delaunay layers: the prisms were given "
                      f"up) | {foam['max_non_orthogonality_deg']:.1f} | - | {100 * layers['coverage']:.1f}% | - | - | "
                      f"{foam['absorbed_tets']} | {verdict} |")
                sys.stdout.flush()
                continue
            print(f"| {name} | {100 * foam['intact_prism_share']:.1f}% | {foam['max_non_orthogonality_deg']:.1f} | "
                  f"{foam['tet_cells_min_dihedral_deg']:.2f} | {100 * layers['coverage']:.1f}% | {volume['stack_shortened_nodes']} of {layers['wall_nodes']} | "
                  f"{volume['stack_whole_columns']} of {layers['eligible_wall_nodes']}, "
                  f"{volume['stack_height_mean']:.2f}, {volume['stack_height_min']:.2f} | {foam['absorbed_tets']} | "
                  f"{verdict} |")
            sys.stdout.flush()
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
