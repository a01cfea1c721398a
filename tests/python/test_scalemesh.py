"""The Python module scalemesh with gmsh.py in one process.

A tube built and meshed in 2D by gmsh.py is meshed by scalemesh.mesh_gmsh_model:
the C++ library reads the model gmsh.py built (its physical surfaces become the
patches) and gmsh.py then reads the volume the library added. The same surface,
written to a file, gives `scalemesh run` the same mesh.

Run by ctest (test python_module) with PYTHONPATH set to the module's
directory and SCALEMESH_BINARY to the scalemesh command.
"""

import json
import locale
import os
import subprocess
import tempfile
import time
import unittest
from collections import Counter

try:
    import gmsh
    import numpy as np
except ImportError as error:  # a missing dependency fails the run, loudly
    raise ImportError(f"{error}: install the Debian packages python3-gmsh and python3-numpy (setup.sh)") from error
try:
    import scalemesh
except ImportError as error:
    raise ImportError(f"{error}: build the target scalemesh_python and put build/python on PYTHONPATH") from error

RADIUS, LENGTH = 3.0, 30.0  # mm


def build_tube(names=("wall", "outlet", "inlet")):
    """An OCC cylinder along z, meshed in 2D; physical surfaces for its side and caps."""
    gmsh.model.add("tube")
    gmsh.model.occ.addCylinder(0, 0, -LENGTH / 2, 0, 0, LENGTH, RADIUS)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.6)
    gmsh.model.mesh.generate(2)
    # The OCC cylinder's surfaces: 1 the side, 2 the cap at z = +15, 3 at z = -15.
    for tag, name in zip((1, 2, 3), names):
        centre = gmsh.model.occ.getCenterOfMass(2, tag)
        expected_z = {1: 0.0, 2: LENGTH / 2, 3: -LENGTH / 2}[tag]
        assert abs(centre[2] - expected_z) < 1e-9, f"surface {tag} is not where the test expects it"
        gmsh.model.addPhysicalGroup(2, [tag], tag)
        gmsh.model.setPhysicalName(2, tag, name)


def model_triangles(entities=None):
    """Node coordinates (N, 3) and triangles (M, 3) as 0-based indices, of the current model's surfaces."""
    tags, coords, _ = gmsh.model.mesh.getNodes()
    index = {int(t): i for i, t in enumerate(tags)}
    corners = []
    for entity in entities if entities is not None else [t for _, t in gmsh.model.getEntities(2)]:
        _, nodes = gmsh.model.mesh.getElementsByType(2, entity)
        corners.extend(index[int(n)] for n in nodes)
    return np.asarray(coords, dtype=float).reshape(-1, 3), np.asarray(corners, dtype=np.int64).reshape(-1, 3)


def enclosed_volume(points, triangles):
    a, b, c = (points[triangles[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


def tet_volumes(points, tets):
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6


def boundary_faces(tets):
    """Faces of the tets used once, as sorted node triples."""
    faces = Counter()
    for t in tets:
        for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            faces[tuple(sorted(int(t[k]) for k in f))] += 1
    assert max(faces.values()) <= 2, "a face is shared by more than two tets"
    return {f for f, n in faces.items() if n == 1}


class GmshSession(unittest.TestCase):
    def setUp(self):
        gmsh.initialize()
        gmsh.option.setNumber("General.Terminal", 0)

    def tearDown(self):
        gmsh.finalize()


class TestMeshGmshModel(GmshSession):
    def test_tube_volume_is_added_to_the_model(self):
        build_tube()
        input_points, input_triangles = model_triangles()
        input_volume = enclosed_volume(input_points, input_triangles)
        result = scalemesh.mesh_gmsh_model(threads=2)

        # The C++ side read the model gmsh.py built: its physical surfaces are the patches.
        self.assertEqual(sorted(result["patch_names"]), ["inlet", "outlet", "wall"])
        self.assertEqual(len(result["patch_surfaces"]), 3)

        # gmsh.py sees what the C++ side added: a discrete volume with the tets.
        volume = result["volume"]
        self.assertIn((3, volume), gmsh.model.getEntities(3))
        self.assertEqual(gmsh.model.getType(3, volume), "Discrete volume")
        tet_tags, tet_nodes = gmsh.model.mesh.getElementsByType(4, volume)
        self.assertEqual(len(tet_tags), len(result["tets"]))
        node_tags, coords, _ = gmsh.model.mesh.getNodes()
        position = {int(t): i for i, t in enumerate(node_tags)}
        coords = np.asarray(coords).reshape(-1, 3)
        tets = np.array([position[int(n)] for n in tet_nodes]).reshape(-1, 4)
        volumes = tet_volumes(coords, tets)
        self.assertGreater(volumes.min(), 0.0, "a tet in the model is not positively oriented")

        # The boundary of the tets is closed, encloses the input's volume
        # (smoothing and remeshing conserve it) and is exactly the triangles
        # of the discrete surfaces bounding the new volume, one per patch.
        boundary = boundary_faces(tets)
        edges = Counter()
        for f in boundary:
            for e in ((f[0], f[1]), (f[0], f[2]), (f[1], f[2])):
                edges[e] += 1
        self.assertEqual(set(edges.values()), {2}, "the boundary of the tets is not closed")
        self.assertAlmostEqual(volumes.sum() / input_volume, 1.0, delta=1e-9)
        _, bounding = gmsh.model.getAdjacencies(3, volume)
        self.assertEqual(sorted(bounding), sorted(result["patch_surfaces"]))
        on_surfaces = set()
        for surface in result["patch_surfaces"]:
            self.assertEqual(gmsh.model.getType(2, surface), "Discrete surface")
            _, nodes = gmsh.model.mesh.getElementsByType(2, surface)
            triangles = {tuple(sorted(position[int(n)] for n in nodes[i:i + 3])) for i in range(0, len(nodes), 3)}
            self.assertTrue(triangles, f"surface {surface} holds no triangles")
            self.assertFalse(triangles & on_surfaces, "a boundary triangle is on two surfaces")
            on_surfaces |= triangles
        self.assertEqual(on_surfaces, boundary)

        # Physical groups as mesh.msh has them: the volume "fluid" and one
        # per patch, named as the patch, holding the new surfaces (the input
        # groups of those names were moved onto them, keeping their tags).
        self.assertEqual(gmsh.model.getPhysicalName(3, result["volume_group"]), "fluid")
        self.assertEqual(list(gmsh.model.getEntitiesForPhysicalGroup(3, result["volume_group"])), [volume])
        for patch, name in enumerate(result["patch_names"]):
            group = result["patch_groups"][patch]
            self.assertEqual(gmsh.model.getPhysicalName(2, group), name)
            self.assertEqual(list(gmsh.model.getEntitiesForPhysicalGroup(2, group)), [result["patch_surfaces"][patch]])
        self.assertEqual({result["patch_names"][p] for p in range(3)},
                         {gmsh.model.getPhysicalName(2, g) for _, g in gmsh.model.getPhysicalGroups(2)})
        # The inlet patch is the cap at z = -15: its boundary triangles lie there.
        inlet = result["patch_names"].index("inlet")
        _, nodes = gmsh.model.mesh.getElementsByType(2, result["patch_surfaces"][inlet])
        inlet_z = coords[[position[int(n)] for n in nodes], 2]
        self.assertLess(np.median(inlet_z), -LENGTH / 2 + 1.0)

        # The views, on the model's nodes and tets.
        self.assertEqual(len(result["views"]), 5)
        self.assertTrue(set(result["views"]) <= set(gmsh.view.getTags()))
        names = [gmsh.option.getString(f"View[{gmsh.view.getIndex(v)}].Name") for v in result["views"]]
        self.assertEqual(names, ["D", "D_out", "d", "layers", "aspect_ratio"])
        surface_points = result["surface_points"]
        first_node = result["first_node_tag"]
        for view, field in zip(result["views"][:4], ("D", "D_out", "d", "layers")):
            kind, tags, data, _, components = gmsh.view.getHomogeneousModelData(view, 0)
            self.assertEqual(kind, "NodeData")
            self.assertEqual(components, 1)
            self.assertEqual(list(tags), list(range(first_node, first_node + surface_points)))
            np.testing.assert_array_equal(np.asarray(data), result[field][:surface_points])
        kind, tags, data, _, _ = gmsh.view.getHomogeneousModelData(result["views"][4], 0)
        self.assertEqual(kind, "ElementData")
        self.assertEqual(sorted(int(t) for t in tags), sorted(int(t) for t in tet_tags))
        np.testing.assert_array_equal(np.asarray(data), result["aspect_ratio"])
        self.assertTrue(np.all(np.isfinite(result["d"][:surface_points])))
        self.assertTrue(np.all(result["d"][:surface_points] > 0))

    def test_the_meshed_input_volume_leaves_the_model(self):
        # The OCC cylinder (volume 1) the tube was meshed from goes: left in
        # the model, generate(3) would fill it with Gmsh's tets beside the
        # result's, which stays as it is.
        build_tube()
        self.assertEqual(gmsh.model.getEntities(3), [(3, 1)])
        result = scalemesh.mesh_gmsh_model(threads=2)
        self.assertEqual(result["removed_volumes"], [1])
        self.assertEqual(gmsh.model.getEntities(3), [(3, result["volume"])])
        for surface in (1, 2, 3):  # the input surfaces stay, with their triangles
            self.assertGreater(len(gmsh.model.mesh.getElementsByType(2, surface)[0]), 0)
        gmsh.model.mesh.generate(3)
        self.assertEqual(gmsh.model.getEntities(3), [(3, result["volume"])])
        tet_tags, _ = gmsh.model.mesh.getElementsByType(4)
        self.assertEqual(len(tet_tags), len(result["tets"]))

    def test_a_volume_beside_another_stays(self):
        # A vessel inside a tissue block (OCC fragments: the cylinder's
        # surfaces bound both volumes): neither is taken for the input and
        # removed, though the vessel's surfaces are all selected.
        gmsh.model.add("tissue")
        block = gmsh.model.occ.addBox(-6, -6, -LENGTH / 2, 12, 12, LENGTH)
        vessel = gmsh.model.occ.addCylinder(0, 0, -LENGTH / 2 - 5, 0, 0, LENGTH + 10, RADIUS)
        gmsh.model.occ.intersect([(3, vessel)], [(3, gmsh.model.occ.copy([(3, block)])[0][1])])
        gmsh.model.occ.fragment([(3, block)], gmsh.model.occ.getEntities(3))
        gmsh.model.occ.synchronize()
        volumes = gmsh.model.getEntities(3)
        self.assertEqual(len(volumes), 2)
        inner = min(volumes, key=lambda v: gmsh.model.occ.getMass(*v))
        _, surfaces = gmsh.model.getAdjacencies(*inner)
        gmsh.model.addPhysicalGroup(2, list(surfaces), 10)
        gmsh.model.setPhysicalName(2, 10, "vessel")
        gmsh.option.setNumber("Mesh.MeshSizeMax", 0.6)
        gmsh.model.mesh.generate(2)
        result = scalemesh.mesh_gmsh_model("vessel", threads=2)
        self.assertEqual(result["removed_volumes"], [])
        for volume in volumes:
            self.assertIn(volume, gmsh.model.getEntities(3))

    def test_same_mesh_as_scalemesh_run(self):
        build_tube()
        binary = os.environ.get("SCALEMESH_BINARY")
        self.assertTrue(binary and os.access(binary, os.X_OK), "SCALEMESH_BINARY does not name the scalemesh command")
        with tempfile.TemporaryDirectory() as case:
            # The surface without physical groups (a labelled .msh makes
            # `scalemesh run` take its flat labelled caps out as openings, a
            # different mesh), binary so that the coordinates are exact.
            gmsh.option.setNumber("Mesh.Binary", 1)
            groups = [(d, t, gmsh.model.getPhysicalName(d, t), list(gmsh.model.getEntitiesForPhysicalGroup(d, t)))
                      for d, t in gmsh.model.getPhysicalGroups()]
            gmsh.model.removePhysicalGroups()
            gmsh.write(os.path.join(case, "surface_in.msh"))
            for d, t, name, entities in groups:
                gmsh.model.addPhysicalGroup(d, entities, t)
                gmsh.model.setPhysicalName(d, t, name)
            with open(os.path.join(case, "scalemesh.toml"), "w") as f:
                # mesh.msh binary too: ASCII MSH holds 16 significant digits,
                # which moves about half of the coordinates by one ulp.
                f.write('[input]\nfile = "surface_in.msh"\n[output]\nvolume = ["mesh.msh"]\nmsh_binary = true\n'
                        'openfoam = false\n[run]\nthreads = 2\n')
            result = scalemesh.mesh_gmsh_model(threads=2)
            run = subprocess.run([binary, "run", case], capture_output=True, text=True)
            self.assertEqual(run.returncode, 0, run.stderr)
            with open(os.path.join(case, "report.json")) as f:
                report = json.load(f)
            gmsh.model.add("run")
            gmsh.merge(os.path.join(case, "mesh.msh"))
            tags, coords, _ = gmsh.model.mesh.getNodes()
            _, nodes = gmsh.model.mesh.getElementsByType(4)
        order = np.argsort(tags)
        points = np.asarray(coords).reshape(-1, 3)[order]
        position = {int(t): i for i, t in enumerate(np.asarray(tags)[order])}
        tets = np.array([position[int(n)] for n in nodes]).reshape(-1, 4)

        self.assertEqual(len(tets), len(result["tets"]))
        self.assertEqual(report["volume"]["tets"], len(result["tets"]))
        self.assertEqual(tet_volumes(points, tets).sum(), tet_volumes(result["points"], result["tets"]).sum())
        # The same points in the same order, and the same tets: the same run.
        np.testing.assert_array_equal(points, result["points"])
        np.testing.assert_array_equal(tets, result["tets"])


class TestMeshSurface(GmshSession):
    def test_gmsh_layout_and_numpy_give_the_same_mesh(self):
        build_tube()
        tags, coords, _ = gmsh.model.mesh.getNodes()
        _, corner_tags = gmsh.model.mesh.getElementsByType(2)
        # gmsh.py's flat layout, as lists, with node tags.
        # gmsh_session=True: the default prism layers' core goes through
        # this gmsh.py session, which is left as it was.
        from_tags = scalemesh.mesh_surface(list(coords), list(corner_tags), node_tags=list(tags), threads=2,
                                           gmsh_session=True)
        points, triangles = model_triangles()
        from_arrays = scalemesh.mesh_surface(points, triangles, threads=2, gmsh_session=True)
        self.assertEqual(from_tags["points"].shape[1], 3)
        self.assertEqual(from_tags["tets"].shape[1], 4)
        np.testing.assert_array_equal(from_tags["points"], from_arrays["points"])
        np.testing.assert_array_equal(from_tags["tets"], from_arrays["tets"])
        n, t = len(from_arrays["points"]), len(from_arrays["tets"])
        for field in ("D", "D_out", "d", "layers"):
            self.assertEqual(from_arrays[field].shape, (n,))
        self.assertEqual(from_arrays["aspect_ratio"].shape, (t,))
        self.assertGreater(tet_volumes(from_arrays["points"], from_arrays["tets"]).min(), 0.0)
        self.assertAlmostEqual(tet_volumes(from_arrays["points"], from_arrays["tets"]).sum()
                               / enclosed_volume(points, triangles), 1.0, delta=1e-9)

    def test_labels_become_named_patches(self):
        build_tube()
        parts = [model_triangles([entity]) for entity in (1, 3, 2)]  # wall, inlet, outlet
        points = parts[0][0]  # every part indexes all the model's nodes
        triangles = np.vstack([t for _, t in parts])
        labels = np.concatenate([np.full(len(t), patch) for patch, (_, t) in enumerate(parts)])
        result = scalemesh.mesh_surface(points, triangles, labels, label_names=["wall", "inlet"], threads=2,
                                        gmsh_session=True)
        self.assertEqual(result["patch_names"], ["wall", "inlet", "patch_2"])
        self.assertEqual(result["boundary_patch"].shape, (len(result["boundary_triangles"]),))
        centroid_z = result["points"][result["boundary_triangles"]].mean(axis=1)[:, 2]
        self.assertTrue(np.all(centroid_z[result["boundary_patch"] == 1] < 0))
        self.assertTrue(np.all(centroid_z[result["boundary_patch"] == 2] > 0))

    def test_the_keywords_and_defaults_are_the_options_table(self):
        # Issue 44: the keywords, defaults() and the docstring come from the
        # one table of the meshing options that `scalemesh options --json` prints.
        listed = json.loads(subprocess.run([os.environ["SCALEMESH_BINARY"], "options", "--json"],
                                           stdout=subprocess.PIPE, check=True, universal_newlines=True).stdout)
        defaults = scalemesh.defaults()
        self.assertEqual(set(defaults), {o["keyword"] for o in listed})
        for option in listed:
            self.assertEqual(defaults[option["keyword"]], option["default"], option["keyword"])
            self.assertIn("  %s (" % option["keyword"], scalemesh.__doc__)

    def test_options_are_the_case_file_defaults_and_are_checked(self):
        defaults = scalemesh.defaults()
        self.assertEqual((defaults["K"], defaults["M"], defaults["G"]), (4.2, 7.0, 0.85))
        self.assertEqual(defaults["layers"], "prisms")
        build_tube()
        points, triangles = model_triangles()
        with self.assertRaisesRegex(ValueError, "growth"):
            scalemesh.mesh_surface(points, triangles, growth=5.0)
        with self.assertRaisesRegex(ValueError, "layers"):
            scalemesh.mesh_surface(points, triangles, layers="wedges")
        with self.assertRaisesRegex(TypeError, "unexpected keyword argument 'grwth'"):
            scalemesh.mesh_surface(points, triangles, grwth=1.2)
        with self.assertRaisesRegex(ValueError, "is not a length"):
            scalemesh.mesh_surface(points, triangles, L_min="two")
        # A value of another type: a TypeError naming the option, not
        # pybind11's RuntimeError.
        with self.assertRaisesRegex(TypeError, "^M = 'seven' is not of the option's type"):
            scalemesh.mesh_surface(points, triangles, M="seven")
        with self.assertRaisesRegex(TypeError, "^curvature = 'yes' is not of the option's type"):
            scalemesh.mesh_surface(points, triangles, curvature="yes")
        stages = []
        scalemesh.mesh_surface(points, triangles, M=5, L_min="0.5 voxels", threads=2, gmsh_session=True,
                               progress=lambda stage, seconds, summary: stages.append((stage, seconds)))
        self.assertIn("volume", [s for s, seconds in stages if seconds >= 0])


class TestErrors(GmshSession):
    def test_bad_input_raises_value_error_with_the_library_message(self):
        build_tube()
        points, triangles = model_triangles()
        with self.assertRaisesRegex(ValueError, "names point"):
            scalemesh.mesh_surface(points, triangles + len(points))
        with self.assertRaisesRegex(ValueError, "hole"):  # open ends are vessel ends; one triangle's gap is not
            scalemesh.mesh_surface(points, triangles[:-1])
        with self.assertRaisesRegex(ValueError, "node tag"):
            scalemesh.mesh_surface(points, triangles + 10 ** 9, node_tags=np.arange(1, len(points) + 1))
        with self.assertRaisesRegex(ValueError, "integers"):
            scalemesh.mesh_surface(points, triangles.astype(float))
        with self.assertRaisesRegex(ValueError, "no physical surface named 'vessel'.*wall"):
            scalemesh.mesh_gmsh_model("vessel")

    def test_a_second_call_on_the_meshed_model_is_refused(self):
        # The model now holds the first result: its boundary surfaces would be
        # meshed again on top of the input (a surface that overlaps itself).
        build_tube()
        first = scalemesh.mesh_gmsh_model(threads=2)
        start = time.monotonic()
        with self.assertRaisesRegex(ValueError, f"bounds volume entity {first['volume']}, which already holds a "
                                                "volume mesh.*physical_group"):
            scalemesh.mesh_gmsh_model(threads=2)
        self.assertLess(time.monotonic() - start, 10)
        # The result is left as it was.
        tet_tags, _ = gmsh.model.mesh.getElementsByType(4, first["volume"])
        self.assertEqual(len(tet_tags), len(first["tets"]))

    def test_a_model_without_a_2d_mesh_is_refused(self):
        gmsh.model.add("empty")
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        with self.assertRaisesRegex(ValueError, "has no triangles"):
            scalemesh.mesh_gmsh_model()


class TestWithoutSession(unittest.TestCase):
    def test_a_finalized_session_is_refused(self):
        gmsh.initialize()
        gmsh.finalize()
        with self.assertRaisesRegex(ValueError, "gmsh.initialize"):
            scalemesh.mesh_gmsh_model()


class TestLocale(unittest.TestCase):
    def test_lengths_read_alike_under_a_comma_locale(self):
        # Under a locale whose decimal separator is a comma (compiled here
        # from glibc's de_DE source, which the locales package ships),
        # "0.5 mm" is still a length: the call gets as far as the surface,
        # which it refuses for its own reason.
        with tempfile.TemporaryDirectory() as scratch:
            compiled = os.path.join(scratch, "de_DE.UTF-8")
            subprocess.run(["localedef", "-c", "-i", "de_DE", "-f", "UTF-8", compiled], capture_output=True)
            self.assertTrue(os.path.exists(os.path.join(compiled, "LC_NUMERIC")),
                            "localedef could not compile de_DE (setup.sh installs the locales package)")
            previous = locale.setlocale(locale.LC_NUMERIC)
            previous_path = os.environ.get("LOCPATH")
            os.environ["LOCPATH"] = scratch
            try:
                locale.setlocale(locale.LC_NUMERIC, "de_DE.UTF-8")
                self.assertEqual(locale.localeconv()["decimal_point"], ",")
                with self.assertRaisesRegex(ValueError, "the surface has no triangles"):
                    scalemesh.mesh_surface(np.zeros((0, 3)), np.zeros((0, 3)), L_min="0.5 mm")
                with self.assertRaisesRegex(ValueError, "L_min = '0,5 mm' is not a length"):
                    scalemesh.mesh_surface(np.zeros((0, 3)), np.zeros((0, 3)), L_min="0,5 mm")
            finally:
                locale.setlocale(locale.LC_NUMERIC, previous)
                if previous_path is None:
                    del os.environ["LOCPATH"]
                else:
                    os.environ["LOCPATH"] = previous_path


if __name__ == "__main__":
    unittest.main()
