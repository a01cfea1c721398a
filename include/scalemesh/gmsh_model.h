#pragma once
// scalemesh inside a Gmsh session: the surface mesh of the current Gmsh model
// in, the layered tetrahedral mesh added to the same model, with physical
// groups and views as the mesh.msh of `scalemesh run` has them. For hosts
// that already use the Gmsh SDK (C++, or Python through the scalemesh module,
// which shares the process's libgmsh).
//
// The host owns the Gmsh session: scalemesh never calls gmsh::initialize or
// gmsh::finalize, and calls Gmsh from the calling thread only. With
// layers = "prisms" it meshes the core on a model of its own beside the
// host's, with options of its own, and removes the model and restores the
// options and the current model before returning. Gmsh is not thread safe:
// the host must not call Gmsh from another thread during the call.
//
// This header needs no Gmsh header, and scalemesh::scalemesh links no Gmsh
// for its users: the host links the Gmsh SDK it calls itself (Debian's
// libgmsh-dev ships gmsh.h and libgmsh.so but no CMake package:
// find_path(gmsh.h) and find_library(gmsh)). libscalemesh.so links the same
// libgmsh.so.4.8 by its soname, so the dynamic loader keeps one copy and the
// host's session is the library's.

#include "scalemesh/mesh.h"

#include <string>
#include <vector>

namespace scalemesh {

struct GmshModelOptions {
    // Name of a physical surface group (dimension 2) whose surface entities
    // are meshed; empty: every surface entity of the model.
    std::string physical_group;
    // Name of the physical volume added for the tets.
    std::string volume_name = "fluid";
    // Add the views D, D_out, d, layers (NodeData on the boundary nodes, mm)
    // and aspect_ratio (ElementData on the tets).
    bool views = true;
};

// What mesh_gmsh_model added to the current model, and the mesh itself.
struct GmshModelResult {
    MeshResult mesh;                  // as mesh_surface returns it, its run kept for write_openfoam,
                                      // write_msh and report_json (whose patches are all walls)
    int volume = -1;                  // tag of the discrete volume entity holding the tets
    std::vector<int> patch_surfaces;  // patch id -> tag of its discrete surface entity (-1: patch without triangles)
    int volume_group = -1;            // tag of the physical volume `volume_name`
    std::vector<int> patch_groups;    // patch id -> tag of its physical surface (-1: patch without triangles)
    std::size_t first_node_tag = 0;   // mesh point i is Gmsh node first_node_tag + i
    std::size_t first_tet_tag = 0;    // mesh tet t is Gmsh element first_tet_tag + t
    std::vector<int> views;           // tags of the views added, in the order D, D_out, d, layers, aspect_ratio
    std::vector<int> removed_volumes; // tags of the input volumes removed from the model (mesh_gmsh_model)
};

// Meshes the 3-node triangles of the current Gmsh model's surface entities
// (all, or those of options.physical_group) with mesh_surface, and adds to
// the same model:
//   - one discrete surface entity per patch holding its boundary triangles,
//     and one discrete volume entity bounded by them holding the tets and
//     every node of the mesh (new node and element tags, above the model's
//     largest);
//   - a physical volume `volume_name` and one physical surface per patch
//     named as the patch. Gmsh keeps physical names unique per dimension, so
//     a physical group of the model with the same dimension and name (the
//     input's "inlet", say) is replaced by the new one, which keeps its tag:
//     the input surface entities leave that group, and gmsh::write then
//     saves the volume mesh with its named patches, as mesh.msh has them;
//   - with options.views, the views of the mesh's fields.
// And it removes from the model the volume entities it meshed, so that a
// later gmsh::model::mesh::generate(3) does not fill them with Gmsh's own
// tets on top of scalemesh's: each volume all of whose boundary surfaces
// were selected, that holds no volume mesh, is in no physical volume group
// and shares none of its surfaces with another volume (the OCC solid a host
// meshed in 2D, say; with physical_group selecting only part of a solid's
// surfaces, the solid stays). Only from the model, not recursively (its
// surfaces stay); a later gmsh::model::occ::synchronize (or geo) restores it
// from the CAD kernel. GmshModelResult::removed_volumes names them.
// Patches: each input surface entity that belongs to a physical surface
// whose name is not "wall" (other than options.physical_group) gives its
// triangles the label of that name; the rest are "wall", patch 0. Each
// boundary triangle of the mesh takes the label of the nearest input
// triangle (mesh_surface).
//
// Precondition: the host called gmsh::initialize and made or merged a model
// with a 2D mesh. Gmsh 4.8 has no gmsh::isInitialized; a session that was
// never initialized, or was finalized, is recognised by its empty model list
// or by the error Gmsh reports, and refused with InputError.
//
// Throws InputError for a session without a model, an unknown physical
// group, surface entities without triangles or with other 2D elements
// (quadrangles, second-order triangles), an entity in two patch groups, a
// surface that is not closed and 2-manifold, options with openings (the
// model's patches are its physical surfaces), or bad options; StageError when
// a stage fails, or when Gmsh refuses an addition (the model may then hold
// part of the additions).
SCALEMESH_API GmshModelResult mesh_gmsh_model(const GmshModelOptions& model = {},
                                            const MeshOptions& options = {});

} // namespace scalemesh
