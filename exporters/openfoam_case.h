#pragma once
// A runnable OpenFOAM case around a written polyMesh: system/, constant/ and
// 0/ for steady, laminar, incompressible flow with simpleFoam (OpenFOAM v1912).

#include "core/atomic_file.h"

#include <filesystem>
#include <string>
#include <vector>

namespace scalemesh {

enum class PatchRole { Wall, Inlet, Outlet };

struct FlowSettings {
    double kinematic_viscosity = 3.3e-6; // m^2/s; blood is about 3.3e-6, air 1.5e-5
    double inlet_speed = 0.1;            // m/s, uniform (plug) inflow normal to each inlet
    int iterations = 2000;               // SIMPLE iterations at most; residual control stops earlier
    // Above 1: the mesh is also written as that many processor meshes
    // (write_decomposed_polymesh), and the flow is solved on them.
    int processors = 1;
    // As PolyMeshOptions::staged: where given, the files are handed over
    // uncommitted.
    StagedOutputs* staged = nullptr;
};

// Writes system/{controlDict,fvSchemes,fvSolution}, constant/{transportProperties,
// turbulenceProperties} and, when the mesh has at least one inlet and one
// outlet, 0/U and 0/p: no-slip walls, a fixed normal inflow at each inlet,
// zero pressure at each outlet. A case without openings gets the system/ and
// constant/ files (so checkMesh and paraFoam work) and no 0/ fields, since
// no flow problem is posed. Beside them an executable `Allrun` (plain bash,
// for Debian's OpenFOAM): checkMesh, then simpleFoam when the flow fields are
// written, each into log.<tool>, exiting non-zero when a tool fails or
// checkMesh finds a failed check. With settings.processors above 1, also
// processor<i>/0/U and p (the same fields, the processor patches given
// `type processor` through their group), and Allrun checks the pieces with
// `mpirun -np N checkMesh -parallel`, solves with `mpirun -np N simpleFoam
// -parallel` and puts the last time back together with reconstructPar.
// Patch names and roles are those of the polyMesh
// boundary file, in its order. Every file is written atomically. Throws
// InputError for a non-positive viscosity or speed, IoError on write failure.
// Returns whether the flow fields (0/) were written.
bool write_openfoam_case(const std::filesystem::path& case_dir, const std::vector<std::string>& patch_names,
                         const std::vector<PatchRole>& roles, const FlowSettings& settings = {});

} // namespace scalemesh
