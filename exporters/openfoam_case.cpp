#include "exporters/openfoam_case.h"

#include "core/atomic_file.h"
#include "core/errors.h"
#include "exporters/foam_file.h"

#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>

namespace scalemesh {

namespace {

std::string header(const std::string& cls, const std::string& location, const std::string& object)
{
    return "FoamFile\n{\n    version     2.0;\n    format      ascii;\n    class       " + cls +
           ";\n    location    \"" + location + "\";\n    object      " + object + ";\n}\n\n";
}

class CaseFiles {
public:
    explicit CaseFiles(std::filesystem::path dir) : dir_(std::move(dir)) {}

    // An OpenFOAM file: `text`, its header included.
    void add(const std::string& relative, const std::string& text) { write_foam_file(dir_ / relative, text, outputs_); }

    // A script, executable by everyone who may read it.
    void add_script(const std::string& relative, const std::string& text)
    {
        const std::filesystem::path path = dir_ / relative;
        outputs_.push_back(std::make_unique<AtomicOutput>(path, true));
        {
            std::ofstream out(outputs_.back()->temporary());
            out << text;
            if (!out.flush()) throw IoError(path.string(), "cannot write the file");
        }
        using std::filesystem::perms;
        std::error_code ec;
        std::filesystem::permissions(outputs_.back()->temporary(),
                                     perms::owner_all | perms::group_read | perms::group_exec | perms::others_read |
                                         perms::others_exec,
                                     ec);
        if (ec) throw IoError(path.string(), "cannot make the script executable: " + ec.message());
    }

    void commit(StagedOutputs* staged) { commit_or_stage(outputs_, staged); }

private:
    std::filesystem::path dir_;
    std::vector<std::unique_ptr<AtomicOutput>> outputs_;
};

// Plain bash for Debian's OpenFOAM (tools on PATH, no RunFunctions): each
// tool's output in log.<tool>, a non-zero exit naming the log when one
// fails. checkMesh exits 0 even when a check fails, so its log is read.
std::string allrun_script(bool flow, int processors)
{
    std::string text = R"SH(#!/bin/bash
# Written by scalemesh: checks the mesh)SH" + std::string(flow ? " and runs the steady laminar flow (simpleFoam)" : "") +
                       R"SH( with
# OpenFOAM (Debian package openfoam), each tool's output in log.<tool>.
# Exits non-zero, naming the log, when a tool fails.
cd "$(dirname "$0")" || exit 1
export WM_PROJECT_DIR="${WM_PROJECT_DIR:-/usr/share/openfoam}"

fail() {
    echo "Allrun: $1" >&2
    [ -f "$2" ] && tail -n 20 "$2" >&2
    exit 1
}

run() {
    command -v "$1" >/dev/null 2>&1 ||
        fail "$1 not found: install the Debian package openfoam, or source OpenFOAM's etc/bashrc"
    echo "Running $1 on $PWD"
    "$1" -case . > "log.$1" 2>&1 || fail "$1 failed (exit code $?); see $PWD/log.$1" "log.$1"
}

run checkMesh
grep -q "^Mesh OK\." log.checkMesh || fail "checkMesh found a failed mesh check; see $PWD/log.checkMesh" log.checkMesh
)SH";
    if (processors <= 1) {
        if (flow) text += "run simpleFoam\n";
        return text;
    }
    // Open MPI refuses root without these, and more ranks than cores
    // without the last.
    text += "\n# The processor meshes processor0 .. processor" + std::to_string(processors - 1) +
            ", each tool's output in log.<tool>.parallel.\nprocessors=" + std::to_string(processors) + R"SH(
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export OMPI_MCA_rmaps_base_oversubscribe=1

prun() {
    command -v mpirun >/dev/null 2>&1 || fail "mpirun not found: install the Debian package openmpi-bin"
    echo "Running $1 on $processors processors on $PWD"
    mpirun -np "$processors" "$1" -parallel -case . > "log.$1.parallel" 2>&1 ||
        fail "$1 failed (exit code $?); see $PWD/log.$1.parallel" "log.$1.parallel"
}

prun checkMesh
grep -q "^Mesh OK\." log.checkMesh.parallel ||
    fail "checkMesh -parallel found a failed mesh check; see $PWD/log.checkMesh.parallel" log.checkMesh.parallel
)SH";
    if (flow)
        text += R"SH(# An earlier solve's times in the pieces belong to the mesh of an earlier run:
# reconstructPar would read them with this mesh's addressing.
find processor*/ -mindepth 1 -maxdepth 1 -type d -regextype posix-extended -regex '.*/[0-9][0-9.eE+-]*' \
    ! -name 0 -exec rm -rf {} +
prun simpleFoam
run reconstructPar
)SH";
    return text;
}

} // namespace

bool write_openfoam_case(const std::filesystem::path& case_dir, const std::vector<std::string>& patch_names,
                         const std::vector<PatchRole>& roles, const FlowSettings& settings)
{
    if (!(settings.kinematic_viscosity > 0) || !std::isfinite(settings.kinematic_viscosity))
        throw InputError("the kinematic viscosity must be a positive number (m^2/s)", "blood is about 3.3e-6");
    if (!(settings.inlet_speed > 0) || !std::isfinite(settings.inlet_speed))
        throw InputError("the inlet speed must be a positive number (m/s)", "give e.g. 0.1");
    if (settings.iterations < 1) throw InputError("the iteration count must be at least 1", "give e.g. 2000");
    if (settings.processors < 1) throw InputError("the processor count must be at least 1", "give decompose = 2 or more, or leave it out");
    if (roles.size() != patch_names.size())
        throw InputError("every patch needs a role (wall, inlet or outlet)", "give one role per patch");

    bool inlet = false, outlet = false;
    for (PatchRole r : roles) {
        inlet = inlet || r == PatchRole::Inlet;
        outlet = outlet || r == PatchRole::Outlet;
    }
    const bool flow = inlet && outlet;

    CaseFiles files(case_dir);
    std::ostringstream control;
    control << header("dictionary", "system", "controlDict") << "application     simpleFoam;\n"
            << "startFrom       startTime;\nstartTime       0;\nstopAt          endTime;\nendTime         "
            << settings.iterations << ";\ndeltaT          1;\nwriteControl    timeStep;\nwriteInterval   "
            << settings.iterations << ";\npurgeWrite      0;\nwriteFormat     ascii;\nwritePrecision  8;\n"
            << "writeCompression off;\ntimeFormat      general;\ntimePrecision   6;\nrunTimeModifiable true;\n";
    files.add("system/controlDict", control.str());

    // Tets and layer prisms: a consistent gradient (pointCellsLeastSquares
    // is exact for a linear field on any cells; Gauss linear is not on
    // skewed ones, and its solutions level off at a wrong value as the mesh
    // is refined: docs/validation.md) with full non-orthogonal correction,
    // and bounded second-order convection. The gradient of U is not
    // cell-limited: the limiter switching on and off held U's residuals on a
    // plateau near 1e-4 on the bifurcation.
    files.add("system/fvSchemes", header("dictionary", "system", "fvSchemes") +
                                      "ddtSchemes { default steadyState; }\n"
                                      "gradSchemes { default pointCellsLeastSquares; }\n"
                                      "divSchemes\n{\n    default none;\n"
                                      "    div(phi,U) bounded Gauss linearUpwind grad(U);\n"
                                      "    div((nuEff*dev2(T(grad(U))))) Gauss linear;\n}\n"
                                      "laplacianSchemes { default Gauss linear corrected; }\n"
                                      "interpolationSchemes { default linear; }\n"
                                      "snGradSchemes { default corrected; }\n");
    files.add("system/fvSolution", header("dictionary", "system", "fvSolution") +
                                       "solvers\n{\n"
                                       "    p { solver GAMG; smoother GaussSeidel; tolerance 1e-8; relTol 0.05; }\n"
                                       "    U { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-9; relTol 0.1; }\n"
                                       "}\n"
                                       "SIMPLE\n{\n    nNonOrthogonalCorrectors 2;\n    consistent yes;\n"
                                       // Four and five orders below the first
                                       // iteration's residuals.
                                       "    residualControl { p 1e-4; U 1e-5; }\n}\n"
                                       "relaxationFactors { equations { U 0.9; \".*\" 0.9; } }\n");
    std::ostringstream transport;
    transport.precision(10);
    transport << header("dictionary", "constant", "transportProperties") << "transportModel  Newtonian;\n"
              << "nu              [0 2 -1 0 0 0 0] " << settings.kinematic_viscosity << ";\n";
    files.add("constant/transportProperties", transport.str());
    files.add("constant/turbulenceProperties",
              header("dictionary", "constant", "turbulenceProperties") + "simulationType  laminar;\n");

    if (flow) {
        std::ostringstream U, p;
        U.precision(10);
        U << header("volVectorField", "0", "U") << "dimensions      [0 1 -1 0 0 0 0];\n"
          << "internalField   uniform (0 0 0);\n\nboundaryField\n{\n";
        p << header("volScalarField", "0", "p") << "dimensions      [0 2 -2 0 0 0 0];\n"
          << "internalField   uniform 0;\n\nboundaryField\n{\n";
        for (size_t i = 0; i < patch_names.size(); ++i) {
            U << "    " << patch_names[i] << "\n    {\n";
            p << "    " << patch_names[i] << "\n    {\n";
            switch (roles[i]) {
            case PatchRole::Wall:
                U << "        type            noSlip;\n";
                p << "        type            zeroGradient;\n";
                break;
            case PatchRole::Inlet:
                // A negative normal value flows into the domain.
                U << "        type            surfaceNormalFixedValue;\n        refValue        uniform "
                  << -settings.inlet_speed << ";\n";
                p << "        type            zeroGradient;\n";
                break;
            case PatchRole::Outlet:
                U << "        type            zeroGradient;\n";
                p << "        type            fixedValue;\n        value           uniform 0;\n";
                break;
            }
            U << "    }\n";
            p << "    }\n";
        }
        U << "}\n";
        p << "}\n";
        files.add("0/U", U.str());
        files.add("0/p", p.str());
        // The processor patches are in the group `processor`, as
        // decomposePar writes them.
        const std::string processor = "    processor\n    {\n        type            processor;\n"
                                      "        value           $internalField;\n    }\n}\n";
        for (int i = 0; i < settings.processors && settings.processors > 1; ++i) {
            const std::string dir = "processor" + std::to_string(i) + "/0/";
            files.add(dir + "U", U.str().substr(0, U.str().size() - 2) + processor);
            files.add(dir + "p", p.str().substr(0, p.str().size() - 2) + processor);
        }
    }

    files.add_script("Allrun", allrun_script(flow, settings.processors));
    files.commit(settings.staged);
    return flow;
}

} // namespace scalemesh
