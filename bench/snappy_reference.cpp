#include "snappy_reference.h"

#include "exporters/surface_writers.h"
#include "references.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>

namespace scalemesh::bench {

namespace fs = std::filesystem;

namespace {

std::string header(const std::string& object)
{
    return "FoamFile { version 2.0; format ascii; class dictionary; object " + object + "; }\n";
}

// The dictionaries blockMesh and snappyHexMesh read. The background block
// covers the surface's box and two cells more on each side; no refinement
// (level 0 on the surface), so the cell size is the one given; layers with
// relative sizes, as the snappyHexMesh tutorials set them.
void write_case(const SurfaceMesh& surface, const SnappyParams& p, const fs::path& dir)
{
    fs::remove_all(dir);
    fs::create_directories(dir / "system");
    fs::create_directories(dir / "constant" / "triSurface");
    write_surface(surface, {}, dir / "constant" / "triSurface" / "surface.stl");

    Vec3 lo, hi;
    bounding_box(surface, lo, hi);
    const double margin = 2 * p.cell_size;
    lo = lo - Vec3{margin, margin, margin};
    hi = hi + Vec3{margin, margin, margin};
    const auto cells = [&](double extent) { return std::max(1L, std::lround(std::ceil(extent / p.cell_size))); };
    const long nx = cells(hi.x - lo.x), ny = cells(hi.y - lo.y), nz = cells(hi.z - lo.z);
    hi = lo + p.cell_size * Vec3{double(nx), double(ny), double(nz)};

    std::ofstream(dir / "system" / "controlDict")
        << header("controlDict")
        << "application snappyHexMesh; startFrom startTime; startTime 0; stopAt endTime; endTime 1; deltaT 1;\n"
           "writeControl timeStep; writeInterval 1; writeFormat binary; writePrecision 12; writeCompression off;\n"
           "timeFormat general; timePrecision 6; runTimeModifiable false;\n";
    std::ofstream(dir / "system" / "fvSchemes")
        << header("fvSchemes")
        << "ddtSchemes { default steadyState; } gradSchemes { default Gauss linear; } divSchemes { default none; }\n"
           "laplacianSchemes { default Gauss linear corrected; } interpolationSchemes { default linear; }\n"
           "snGradSchemes { default corrected; }\n";
    std::ofstream(dir / "system" / "fvSolution") << header("fvSolution");

    std::ostringstream block;
    block.precision(17);
    block << header("blockMeshDict") << "convertToMeters 1;\nvertices (";
    for (int k = 0; k < 2; ++k)
        for (const auto& [i, j] : {std::pair{0, 0}, {1, 0}, {1, 1}, {0, 1}})
            block << " (" << (i ? hi.x : lo.x) << " " << (j ? hi.y : lo.y) << " " << (k ? hi.z : lo.z) << ")";
    block << " );\nblocks ( hex (0 1 2 3 4 5 6 7) (" << nx << " " << ny << " " << nz
          << ") simpleGrading (1 1 1) );\nedges ();\n"
             "boundary ( box { type patch; faces ( (0 3 2 1) (4 5 6 7) (0 1 5 4) (2 3 7 6) (1 2 6 5) (0 4 7 3) ); } );\n";
    std::ofstream(dir / "system" / "blockMeshDict") << block.str();

    std::ostringstream snappy;
    snappy.precision(17);
    snappy << header("snappyHexMeshDict")
           << "castellatedMesh true; snap true; addLayers true;\n"
              "geometry { surface.stl { type triSurfaceMesh; name surface; } }\n"
              "castellatedMeshControls {\n"
              "  maxLocalCells 100000000; maxGlobalCells 200000000; minRefinementCells 0; maxLoadUnbalance 0.1;\n"
              "  nCellsBetweenLevels 3; features (); refinementSurfaces { surface { level (0 0); } }\n"
              "  resolveFeatureAngle 30; refinementRegions {};\n"
              "  locationInMesh ("
           << p.inside.x << " " << p.inside.y << " " << p.inside.z
           << ");\n  allowFreeStandingZoneFaces true;\n}\n"
              "snapControls { nSmoothPatch 3; tolerance 2.0; nSolveIter 30; nRelaxIter 5; nFeatureSnapIter 10;\n"
              "  implicitFeatureSnap false; explicitFeatureSnap false; multiRegionFeatureSnap false; }\n"
              "addLayersControls {\n"
              "  relativeSizes true; layers { \"surface.*\" { nSurfaceLayers "
           << p.layers
           << "; } }\n"
              "  expansionRatio 1.0; finalLayerThickness 0.3; minThickness 0.1; nGrow 0; featureAngle 60;\n"
              "  slipFeatureAngle 30; nRelaxIter 3; nSmoothSurfaceNormals 1; nSmoothNormals 3; nSmoothThickness 10;\n"
              "  maxFaceThicknessRatio 0.5; maxThicknessToMedialRatio 0.3; minMedialAxisAngle 90;\n"
              "  nBufferCellsNoExtrude 0; nLayerIter 50;\n}\n"
              "meshQualityControls {\n"
              "  maxNonOrtho 65; maxBoundarySkewness 20; maxInternalSkewness 4; maxConcave 80; minVol 1e-13;\n"
              "  minTetQuality 1e-15; minArea -1; minTwist 0.02; minDeterminant 0.001; minFaceWeight 0.05;\n"
              "  minVolRatio 0.01; minTriangleTwist -1; nSmoothScale 4; errorReduction 0.75;\n"
              "  relaxed { maxNonOrtho 75; }\n}\n"
              "writeFlags ( ); mergeTolerance 1e-6;\n";
    std::ofstream(dir / "system" / "snappyHexMeshDict") << snappy.str();
}

// Runs an OpenFOAM utility on the case, its output into log.<utility>;
// returns its wall time, or a negative number when it failed.
double run_utility(const std::string& utility, const std::string& options, const fs::path& dir)
{
    const std::string command = "WM_PROJECT_DIR=\"${WM_PROJECT_DIR:-/usr/share/openfoam}\" " + utility + " " +
                                options + " -case '" + dir.string() + "' > '" + (dir / ("log." + utility)).string() +
                                "' 2>&1";
    const auto start = Clock::now();
    const int status = std::system(command.c_str());
    const double seconds = seconds_since(start);
    return status == 0 ? seconds : -1;
}

} // namespace

SnappyRun snappy_hex_mesh(const SurfaceMesh& surface, const SnappyParams& params, const fs::path& dir)
{
    SnappyRun run;
    if (std::system("command -v snappyHexMesh >/dev/null 2>&1 && command -v blockMesh >/dev/null 2>&1") != 0) {
        run.error = "blockMesh or snappyHexMesh not on the PATH (the openfoam package installs them)";
        return run;
    }
    write_case(surface, params, dir);
    const double block = run_utility("blockMesh", "", dir);
    if (block < 0) {
        run.error = "blockMesh failed (" + (dir / "log.blockMesh").string() + ")";
        return run;
    }
    run.snappy_seconds = run_utility("snappyHexMesh", "-overwrite", dir);
    if (run.snappy_seconds < 0) {
        run.error = "snappyHexMesh failed (" + (dir / "log.snappyHexMesh").string() + ")";
        return run;
    }
    run.seconds = block + run.snappy_seconds;

    // The end of the layer stage in the log:
    //   patch   faces    layers   overall thickness
    //   ...
    //   surface 5218     3        0.45      100
    //   Layer mesh : cells:41119  faces:127440  points:46509
    std::ifstream log(dir / "log.snappyHexMesh");
    const std::regex layer_row(R"(^\s*surface\S*\s+(\d+)\s+([0-9.eE+-]+)\s+([0-9.eE+-]+)\s+([0-9.eE+-]+)\s*$)");
    const std::regex layer_mesh(R"(^Layer mesh : cells:(\d+))");
    bool row = false, mesh = false;
    for (std::string line; std::getline(log, line);) {
        std::smatch m;
        if (std::regex_match(line, m, layer_row)) {
            run.mean_layers = std::stod(m[2]);
            run.thickness_percent = std::stod(m[4]);
            row = true;
        } else if (std::regex_search(line, m, layer_mesh)) {
            run.cells = std::stoul(m[1]);
            mesh = true;
        }
    }
    if (!row || !mesh) run.error = "no layer table or final cell count in " + (dir / "log.snappyHexMesh").string();
    return run;
}

} // namespace scalemesh::bench
