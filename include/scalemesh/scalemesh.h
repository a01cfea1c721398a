#pragma once
// The scalemesh library: the mesh functions (scalemesh/mesh.h), meshing the
// current model of a Gmsh session (scalemesh/gmsh_model.h), and the
// exceptions they throw (scalemesh/errors.h). Link the CMake target
// scalemesh::scalemesh (find_package(scalemesh)).

#include "scalemesh/errors.h"
#include "scalemesh/gmsh_model.h"
#include "scalemesh/mesh.h"
