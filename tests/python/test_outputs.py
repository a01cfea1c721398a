"""The library's outputs from Python: a MeshResult's write_openfoam, write_msh,
report and to_meshio, the openings keyword on an open tube, and the type stub.

Run by ctest (test python_module) with the module's directory on PYTHONPATH.
"""

import ast
import collections.abc
import json
import os
import shutil
import subprocess
import tempfile
import unittest

try:
    import gmsh
    import numpy as np
except ImportError as error:  # a missing dependency fails the run, loudly
    raise ImportError(f"{error}: install the Debian packages python3-gmsh and python3-numpy (setup.sh)") from error
import scalemesh

RADIUS, LENGTH = 2.0, 12.0  # mm


def open_tube(radius=RADIUS, length=LENGTH, around=20):
    """A tube along z open at both ends (two loops of `around` edges), outward wound, staggered rings."""
    rings = int(np.ceil(length / (2 * np.pi * radius / around))) + 1
    j, i = np.meshgrid(np.arange(rings), np.arange(around), indexing="ij")
    angle = 2 * np.pi * (i + 0.5 * (j % 2)) / around
    points = np.stack([radius * np.cos(angle), radius * np.sin(angle), -length / 2 + length * j / (rings - 1)], -1)
    at = lambda j, i: j * around + i % around  # noqa: E731
    triangles = []
    for j in range(rings - 1):
        for i in range(around):
            if j % 2 == 0:
                triangles += [(at(j, i), at(j, i + 1), at(j + 1, i)), (at(j, i + 1), at(j + 1, i + 1), at(j + 1, i))]
            else:
                triangles += [(at(j, i), at(j + 1, i + 1), at(j + 1, i)), (at(j, i), at(j, i + 1), at(j + 1, i + 1))]
    return points.reshape(-1, 3), np.asarray(triangles, dtype=np.int64)


OPENINGS = [{"name": "in", "type": "inlet", "near": [0, 0, -LENGTH / 2]},
            {"name": "out", "type": "outlet", "near": (0, 0, LENGTH / 2), "extension": None}]


def check_mesh(case):
    """checkMesh's log on the case, or None when OpenFOAM is not installed."""
    if shutil.which("checkMesh") is None:
        return None
    env = dict(os.environ, WM_PROJECT_DIR=os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam"))
    return subprocess.run(["checkMesh", "-case", case], capture_output=True, text=True, env=env).stdout


class TestOutputs(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.points, cls.triangles = open_tube()
        cls.result = scalemesh.mesh_surface(cls.points, cls.triangles, openings=OPENINGS, threads=2)

    def test_openings_become_patches_in_order(self):
        result = self.result
        self.assertEqual(result["patch_names"], ["wall", "in", "out"])
        z = result["points"][result["boundary_triangles"]][:, :, 2]
        inlet = z[result["boundary_patch"] == 1]
        self.assertGreater(len(inlet), 0)
        self.assertAlmostEqual(float(inlet.min()), float(inlet.max()), delta=1e-9)  # a flat cap
        self.assertLess(float(inlet.max()), -LENGTH / 2 + RADIUS)  # at the inlet's end

    def test_result_is_a_mapping_of_the_arrays(self):
        result = self.result
        self.assertIsInstance(result, collections.abc.Mapping)
        self.assertIn("points", result)
        self.assertEqual(result["points"].shape[1], 3)
        self.assertIs(dict(result)["tets"], result["tets"])
        self.assertEqual(len(result), len(list(result.keys())))
        with self.assertRaises(KeyError):
            result["no such array"]
        self.assertIsNone(result.get("no such array"))

    def test_write_openfoam_writes_a_flow_case(self):
        with tempfile.TemporaryDirectory() as scratch:
            case = os.path.join(scratch, "case")  # made by write_openfoam
            written = self.result.write_openfoam(case, inlet_speed=0.2)
            self.assertTrue(written["flow_fields"])
            self.assertEqual(written["patch_names"], ["wall", "in", "out"])
            self.assertEqual(sum(written["patch_faces"]), len(self.result["boundary_triangles"]))
            for name in ("constant/polyMesh/owner", "system/controlDict", "0/U", "0/p", "Allrun", "report.json"):
                self.assertTrue(os.path.isfile(os.path.join(case, name)), name)
            with open(os.path.join(case, "0", "U")) as f:
                self.assertIn("refValue        uniform -0.2;", f.read())  # inflow: against the outward normal
            with open(os.path.join(case, "report.json")) as f:
                report = json.load(f)
            self.assertEqual(report["openfoam"]["cells"], written["cells"])
            log = check_mesh(case)
            if log is not None:
                self.assertIn("Mesh OK.", log)
            with self.assertRaisesRegex(ValueError, "viscosity"):
                self.result.write_openfoam(os.path.join(scratch, "bad"), viscosity=0.0)
            self.assertFalse(os.path.exists(os.path.join(scratch, "bad")))

    def test_report_is_the_runs_report(self):
        report = self.result.report
        self.assertEqual(report["volume"]["tets"], len(self.result["tets"]))
        self.assertEqual([o["name"] for o in report["openings"]], ["in", "out"])
        self.assertEqual(report["openings"][0]["type"], "inlet")
        self.assertEqual(json.loads(self.result.report_json()), report)

    def test_bad_openings_raise_naming_the_key(self):
        points, triangles = self.points, self.triangles
        with self.assertRaisesRegex(ValueError, "unknown key 'nearby'"):
            scalemesh.mesh_surface(points, triangles, openings=[{"name": "in", "type": "inlet", "nearby": [0, 0, 0]}])
        with self.assertRaisesRegex(ValueError, r"\[openings\] \[1\] type"):
            scalemesh.mesh_surface(points, triangles, openings=[{"name": "in", "type": "sideways", "near": [0, 0, -6]}])
        with self.assertRaisesRegex(ValueError, r"openings\[0\]\['near'\] is not 3 numbers"):
            scalemesh.mesh_surface(points, triangles, openings=[{"name": "in", "type": "inlet", "near": [0, 0]}])
        with self.assertRaisesRegex(TypeError, "not a list of dicts"):
            scalemesh.mesh_surface(points, triangles, openings={"name": "in"})
        with self.assertRaisesRegex(ValueError, "labels"):
            scalemesh.mesh_surface(points, triangles, np.zeros(len(triangles), dtype=np.int64))

    def test_write_msh_through_the_host_session(self):
        gmsh.initialize()
        try:
            gmsh.option.setNumber("General.Terminal", 0)
            gmsh.model.add("host")
            models = gmsh.model.list()
            with tempfile.TemporaryDirectory() as scratch:
                path = os.path.join(scratch, "mesh.msh")
                self.result.write_msh(path, gmsh_session=True)
                self.assertEqual(gmsh.model.getCurrent(), "host")  # the host's model is current again
                self.assertEqual(gmsh.model.list(), models)  # and the scratch model gone
                gmsh.merge(path)
                names = {gmsh.model.getPhysicalName(d, t) for d, t in gmsh.model.getPhysicalGroups()}
                self.assertEqual(names, {"fluid", "wall", "in", "out"})
                _, tets = gmsh.model.mesh.getElementsByType(4)
                self.assertEqual(len(tets), self.result["tets"].size)
        finally:
            gmsh.finalize()

    def test_to_meshio(self):
        try:
            import meshio  # noqa: F401
        except ImportError:
            with self.assertRaisesRegex(ImportError, "meshio"):
                self.result.to_meshio()
            return
        mesh = self.result.to_meshio()
        blocks = {block.type: len(block.data) for block in mesh.cells}
        self.assertEqual(blocks, {"tetra": len(self.result["tets"]), "triangle": len(self.result["boundary_triangles"])})
        np.testing.assert_array_equal(mesh.points, self.result["points"])
        self.assertEqual(set(mesh.field_data), {"wall", "in", "out"})


class TestStub(unittest.TestCase):
    def test_the_stub_names_what_the_module_defines(self):
        stub = os.path.join(os.path.dirname(scalemesh.__file__), "scalemesh.pyi")
        with open(stub) as f:
            tree = ast.parse(f.read())
        functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
        classes = {n.name: n for n in tree.body if isinstance(n, ast.ClassDef)}
        public = {name for name in dir(scalemesh) if not name.startswith("_")}
        self.assertEqual(functions | (set(classes) & public), public)
        methods = {n.name for n in classes["MeshResult"].body if isinstance(n, ast.FunctionDef)}
        defined = {name for name in dir(scalemesh.MeshResult) if not name.startswith("_")}
        self.assertEqual({m for m in methods if not m.startswith("_")}, defined)
        options = set(scalemesh.defaults()) | {"openings", "progress", "gmsh_session"}
        for function in functions - {"defaults"}:
            node = next(n for n in tree.body if getattr(n, "name", "") == function)
            arguments = {a.arg for a in node.args.kwonlyargs}
            self.assertLessEqual(set(scalemesh.defaults()), arguments, function)  # every meshing option
            # The stub's own parameters (not the options) are the module's,
            # in order, positional or keyword-only alike, with defaults alike
            # (pybind11's signature line: "name(a: handle, b: handle = None,
            # *, c: bool = False, **kwargs) -> ...").
            signature = getattr(scalemesh, function).__doc__.splitlines()[0]
            parameters = signature[signature.index("(") + 1:signature.rindex(") ->")].split(", ")
            module_positional, module_keyword, keyword = [], [], False
            for parameter in parameters:
                if parameter == "*":
                    keyword = True
                elif not parameter.startswith("**"):
                    name = parameter.split(":")[0]
                    (module_keyword if keyword else module_positional).append((name, "=" in parameter))
            positional = node.args.args
            first_default = len(positional) - len(node.args.defaults)
            self.assertEqual([(a.arg, i >= first_default) for i, a in enumerate(positional)], module_positional,
                             function)
            stub_keyword = [(a.arg, d is not None) for a, d in zip(node.args.kwonlyargs, node.args.kw_defaults)
                            if a.arg not in options]
            self.assertEqual(stub_keyword, module_keyword, function)


if __name__ == "__main__":
    unittest.main()
