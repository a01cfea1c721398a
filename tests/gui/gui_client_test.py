#!/usr/bin/python3
"""tools/scalemesh_gui.py run by Gmsh itself, as the GUI runs it.

Gmsh 4.8 opens the client file, starts it with `-onelab NAME SOCKET` over its
ONELAB socket and sends it the actions initialize, check and compute; the
parameters come from Gmsh's ONELAB database, preset by a .geo file Gmsh reads
beside the client (SetNumber, DefineConstant). Gmsh runs in batch mode (`-`):
the same server and socket code as the GUI, without the FLTK window, which a
test cannot press Run in. After merging, the client asks Gmsh (test hook
SCALEMESH_GUI_SAVE) to save the model Gmsh now holds and its views; those
files are checked with the python gmsh API.

usage: gui_client_test.py CASE --client tools/scalemesh_gui.py --scalemesh BIN --workdir DIR
CASE: merge (the tube with open ends), error (an input scalemesh refuses),
openings (a .msh surface whose physical surfaces are named in the GUI).
"""

import argparse
import glob
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys

try:
    import gmsh
except ImportError:
    sys.exit("FAIL: the python gmsh module is missing: apt-get install python3-gmsh (bash setup.sh installs it)")

SOURCE_DIR = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
failures = []


def check(condition, what):
    print(("ok    " if condition else "FAIL  ") + what)
    if not condition:
        failures.append(what)


def run_gmsh(args, workdir, params_geo):
    gmsh_binary = shutil.which("gmsh")
    if not gmsh_binary:
        sys.exit("FAIL: the gmsh program is missing: apt-get install gmsh (bash setup.sh installs it)")
    with open(os.path.join(workdir, "params.geo"), "w") as f:
        f.write(params_geo)
    # Gmsh opens its ONELAB socket at $HOME/.gmshsock: each run gets a home
    # of its own, or the tests that ctest runs at once (and a Gmsh the user
    # has open) would meet on one socket.
    home = os.path.join(workdir, "home")
    os.makedirs(home, exist_ok=True)
    env = dict(os.environ, HOME=home, SCALEMESH_BINARY=os.path.abspath(args.scalemesh),
               SCALEMESH_GUI_SAVE=os.path.join(workdir, "merged"))
    command = [gmsh_binary, os.path.abspath(args.client), "params.geo", "-nopopup", "-"]
    print("running " + " ".join(command) + " in " + workdir)
    result = subprocess.run(command, cwd=workdir, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            universal_newlines=True, timeout=600)
    print(result.stdout)
    check(re.search(r'-onelab "scalemesh_gui" \S+', result.stdout) is not None,
          "Gmsh started the client over its ONELAB socket")
    return result


def onelab_database(path):
    """name -> parameter of a ONELAB database file Gmsh saved: a title line,
    then per parameter its byte length, a space, the serialised parameter and
    a newline (onelab.h, parameterSpace::toFile)."""
    data = open(path, "rb").read()
    position = data.index(b"\n") + 1
    held = {}
    while position < len(data):
        space = data.index(b" ", position)
        size = int(data[position:space])
        p = client_module()._parse(data[space + 1:space + 1 + size].decode("utf-8"))
        held[p["name"]] = p
        position = space + 1 + size + 1
    return held


def client_module():
    spec = importlib.util.spec_from_file_location("scalemesh_gui", os.path.join(SOURCE_DIR, "tools",
                                                                                 "scalemesh_gui.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def fresh(workdir):
    shutil.rmtree(workdir, ignore_errors=True)
    os.makedirs(workdir)
    return workdir


def open_model(path):
    gmsh.initialize([], False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.open(path)


def physical_names():
    return {(dim, gmsh.model.getPhysicalName(dim, tag)) for dim, tag in gmsh.model.getPhysicalGroups()}


def view_names():
    return [gmsh.option.getString("View[%d].Name" % gmsh.view.getIndex(v)) for v in gmsh.view.getTags()]


def tetrahedra():
    types, tags, _ = gmsh.model.mesh.getElements(3)
    return sum(len(t) for e, t in zip(types, tags) if e == 4)


def check_merged_model(workdir, case_dir, expected_groups):
    """The model Gmsh saved after the merge against the mesh.msh scalemesh wrote."""
    open_model(os.path.join(case_dir, "mesh.msh"))
    written_tets, written_views = tetrahedra(), view_names()
    gmsh.finalize()
    check(written_tets > 0 and len(written_views) > 0, "scalemesh wrote tetrahedra and views into mesh.msh")

    check(os.path.isfile(os.path.join(workdir, "merged.msh")), "Gmsh saved the model it holds after the merge")
    if failures:
        return
    open_model(os.path.join(workdir, "merged.msh"))
    merged_tets = tetrahedra()
    check(merged_tets == written_tets,
          "Gmsh's model holds the volume mesh: %d tetrahedra, mesh.msh %d" % (merged_tets, written_tets))
    groups = physical_names()
    check(groups == expected_groups, "physical groups in Gmsh's model %s, expected %s"
          % (sorted(groups), sorted(expected_groups)))
    for view_file in sorted(glob.glob(os.path.join(workdir, "merged_view*.pos"))):
        gmsh.merge(view_file)
    merged_views = view_names()
    check(merged_views == written_views,
          "Gmsh holds the views of mesh.msh: %s, mesh.msh %s" % (merged_views, written_views))
    gmsh.finalize()


def case_merge(args):
    workdir = fresh(args.workdir)
    shutil.copy(os.path.join(SOURCE_DIR, "cases", "tube_open", "tube_open.stl"), workdir)
    params = ('DefineConstant[ input = {"%s", Name "scalemesh/0Input file"} ];\n'
              'SetNumber("scalemesh/1Sizing/1M", 9);\n'
              'SetNumber("scalemesh/1Sizing/2K", 3.5);\n') % os.path.join(workdir, "tube_open.stl")
    result = run_gmsh(args, workdir, params)
    check(result.returncode == 0, "gmsh exits with 0 (got %d)" % result.returncode)
    check("Error" not in result.stdout, "no error in Gmsh's messages")
    case_dir = os.path.join(workdir, "tube_open_scalemesh")
    toml = open(os.path.join(case_dir, "scalemesh.toml")).read()
    check("M = 9\n" in toml and "K = 3.5\n" in toml,
          "the case file carries the GUI's M = 9 and K = 3.5")
    check(re.search(r"keep all 4 layers", result.stdout) is not None,
          "scalemesh ran with M = 9 (floor(9/2) = 4 layers) and its messages reached Gmsh")
    check_merged_model(workdir, case_dir, {(3, "fluid"), (2, "wall"), (2, "inlet"), (2, "outlet_1")})


def check_without_a_binary():
    """With no scalemesh to list the options, the client still defines the
    input, binary and case parameters, and says why once."""
    module = client_module()

    class Client:
        def __init__(self):
            self.defined, self.errors = [], []

        def define(self, ptype, name, value, **fields):
            self.defined.append(name)
            return value

        def error(self, text):
            self.errors.append(text)

        def warning(self, text):
            pass

    def no_binary(values):
        raise RuntimeError("cannot find the scalemesh program")

    module.find_binary = no_binary
    client = Client()
    values = module.define_parameters(client)
    check(all(any(n.endswith(end) for n in client.defined) for end in ("Input file", "scalemesh binary",
                                                                        "Case directory")),
          "without a scalemesh binary the input, binary and case parameters are defined: %s" % client.defined)
    check(client.errors == ["cannot find the scalemesh program"] and values["options"] is None,
          "without a scalemesh binary one error says why: %s" % client.errors)


def case_error(args):
    check_without_a_binary()
    workdir = fresh(args.workdir)
    with open(os.path.join(workdir, "broken.stl"), "w") as f:
        f.write("solid broken\nthis is not an STL facet\nendsolid broken\n")
    params = 'DefineConstant[ input = {"%s", Name "scalemesh/0Input file"} ];\n' % os.path.join(workdir, "broken.stl")
    result = run_gmsh(args, workdir, params)
    errors = [l for l in result.stdout.splitlines() if l.startswith("Error")]
    check(any("scalemesh_gui - scalemesh failed (exit code" in l and "scalemesh: error:" in l for l in errors),
          "scalemesh's error line is shown as a Gmsh error: %s" % errors)
    check(result.returncode != 0, "gmsh exits non-zero after the error (got %d)" % result.returncode)
    check(not os.path.exists(os.path.join(workdir, "merged.msh")), "nothing was merged")


def case_openings(args):
    workdir = fresh(args.workdir)
    # A closed tube (radius 2 mm, length 20 mm) whose caps are the physical
    # surfaces "upstream" (z = 0, tag 7) and "downstream" (z = 20, tag 8).
    gmsh.initialize([], False)
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, 20, 2)
    gmsh.model.occ.synchronize()
    caps = {}
    lateral = []
    for _, tag in gmsh.model.getEntities(2):
        z = gmsh.model.occ.getCenterOfMass(2, tag)[2]
        if abs(z) < 1e-6:
            caps["upstream"] = tag
        elif abs(z - 20) < 1e-6:
            caps["downstream"] = tag
        else:
            lateral.append(tag)
    gmsh.model.addPhysicalGroup(2, lateral, 6)
    gmsh.model.setPhysicalName(2, 6, "vessel")
    gmsh.model.addPhysicalGroup(2, [caps["upstream"]], 7)
    gmsh.model.setPhysicalName(2, 7, "upstream")
    gmsh.model.addPhysicalGroup(2, [caps["downstream"]], 8)
    gmsh.model.setPhysicalName(2, 8, "downstream")
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.5)
    gmsh.model.mesh.generate(2)
    surface = os.path.join(workdir, "labelled_tube.msh")
    gmsh.write(surface)
    gmsh.finalize()
    # In the GUI: downstream is the inlet, upstream an outlet; vessel stays
    # automatic (the wall).
    params = ('DefineConstant[ input = {"%s", Name "scalemesh/0Input file"} ];\n'
              'SetNumber("scalemesh/3Openings/downstream (8)", 1);\n'
              'SetNumber("scalemesh/3Openings/upstream (7)", 2);\n') % surface
    result = run_gmsh(args, workdir, params)
    check(result.returncode == 0, "gmsh exits with 0 (got %d)" % result.returncode)
    check("Error" not in result.stdout, "no error in Gmsh's messages")
    case_dir = os.path.join(workdir, "labelled_tube_scalemesh")
    toml = open(os.path.join(case_dir, "scalemesh.toml")).read()
    openings = re.findall(r'\[\[openings\]\]\nname = "(\w+)"\ntype = "(\w+)"\nlabel = (\d+)', toml)
    check(sorted(openings) == [("downstream", "inlet", "8"), ("upstream", "outlet", "7")],
          "the case file names the GUI's openings by label: %s" % openings)
    report = json.load(open(os.path.join(case_dir, "report.json")))
    types = sorted((o["name"], o["type"]) for o in report["openings"])
    check(types == [("downstream", "inlet"), ("upstream", "outlet")],
          "scalemesh made the openings the GUI asked for: %s" % types)
    # Gmsh saves its ONELAB database when it ends: the parameters the client
    # defined are those the GUI shows.
    held = onelab_database(os.path.join(workdir, "params.db"))
    for name, value in [("scalemesh/1Sizing/1M", 7.0), ("scalemesh/3Openings/vessel (6)", 0.0),
                        ("scalemesh/3Openings/upstream (7)", 2.0), ("scalemesh/3Openings/downstream (8)", 1.0),
                        ("scalemesh/0Input file", surface), ("scalemesh/5Result/Case directory", case_dir)]:
        check(name in held and held[name]["values"] == [value],
              "Gmsh's ONELAB database holds %s = %r (got %r)" % (name, value,
                                                                 held[name]["values"] if name in held else None))
    choice = held.get("scalemesh/3Openings/upstream (7)", {})
    check(choice.get("valueLabels") == {0.0: "automatic", 1.0: "inlet", 2.0: "outlet"},
          "an opening is a choice of automatic, inlet, outlet in the GUI: %r" % choice.get("valueLabels"))
    check_merged_model(workdir, case_dir, {(3, "fluid"), (2, "wall"), (2, "downstream"), (2, "upstream")})


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("case", choices=["merge", "error", "openings"])
    parser.add_argument("--client", required=True)
    parser.add_argument("--scalemesh", required=True)
    parser.add_argument("--workdir", required=True)
    args = parser.parse_args()
    {"merge": case_merge, "error": case_error, "openings": case_openings}[args.case](args)
    if failures:
        print("%d check(s) failed" % len(failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
