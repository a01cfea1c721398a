#include "importers/vdb_importer.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/ValueTransformer.h>

#include <fstream>
#include <mutex>

namespace scalemesh {

namespace {

std::once_flag g_openvdb_init;

void initialize_openvdb() { std::call_once(g_openvdb_init, [] { openvdb::initialize(); }); }

// A float copy of any scalar grid, keeping name, class, transform and metadata.
template <typename GridT>
openvdb::FloatGrid::Ptr to_float(const GridT& in)
{
    auto out = openvdb::FloatGrid::create(static_cast<float>(in.background()));
    out->setTransform(in.transform().copy());
    out->setName(in.getName());
    out->setGridClass(in.getGridClass());
    out->tree().topologyUnion(in.tree());
    // Copy voxel and tile values.
    openvdb::tools::foreach(out->beginValueAll(), [&in](const openvdb::FloatGrid::ValueAllIter& it) {
        it.setValue(static_cast<float>(in.tree().getValue(it.getCoord())));
    });
    return out;
}

openvdb::FloatGrid::Ptr as_float_grid(const openvdb::GridBase::Ptr& base)
{
    if (auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(base)) return g;
    if (auto g = openvdb::gridPtrCast<openvdb::DoubleGrid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::Int32Grid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::Int64Grid>(base)) return to_float(*g);
    if (auto g = openvdb::gridPtrCast<openvdb::BoolGrid>(base)) return to_float(*g);
    return nullptr;
}

bool is_scalar_type(const std::string& type)
{
    return type == openvdb::FloatGrid::gridType() || type == openvdb::DoubleGrid::gridType() ||
           type == openvdb::Int32Grid::gridType() || type == openvdb::Int64Grid::gridType() ||
           type == openvdb::BoolGrid::gridType();
}

} // namespace

openvdb::FloatGrid::Ptr read_vdb(const std::filesystem::path& path, const VdbImportParams& params)
{
    initialize_openvdb();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec))
        throw IoError(path.string(), "no such file; check the path");
    {
        // OpenVDB files start with the magic number 0x56444220 ("VDB " little-endian).
        std::ifstream in(path, std::ios::binary);
        uint32_t magic = 0;
        in.read(reinterpret_cast<char*>(&magic), sizeof magic);
        if (!in || magic != 0x56444220u)
            throw InputError(path.string() + " is not an OpenVDB file (wrong magic number)",
                             "give a .vdb file, or a supported image or surface format");
    }

    openvdb::io::File file(path.string());
    openvdb::GridPtrVecPtr grids;
    try {
        file.open(false);
        grids = file.getGrids();
        file.close();
    } catch (const std::exception& e) {
        throw InputError(path.string() + " could not be read as a VDB file: " + e.what(),
                         "the file may be truncated or corrupt; re-export it");
    }

    std::string names;
    openvdb::GridBase::Ptr chosen;
    for (const auto& g : *grids) {
        names += (names.empty() ? "" : ", ") + ("'" + g->getName() + "' (" + g->type() + ")");
        if (params.grid_name.empty() ? (!chosen && is_scalar_type(g->type())) : g->getName() == params.grid_name)
            if (!chosen) chosen = g;
    }
    if (!chosen) {
        if (!params.grid_name.empty())
            throw InputError("grid '" + params.grid_name + "' is not in " + path.string(),
                             "the file holds: " + (names.empty() ? std::string("no grids") : names));
        throw InputError(path.string() + " holds no float or integer grid",
                         "the file holds: " + (names.empty() ? std::string("no grids") : names));
    }
    openvdb::FloatGrid::Ptr grid = as_float_grid(chosen);
    if (!grid)
        throw InputError("grid '" + chosen->getName() + "' has type " + chosen->type() + ", not a scalar grid",
                         "choose a float or integer grid with --grid; the file holds: " + names);
    if (!grid->transform().isLinear())
        throw InputError("grid '" + grid->getName() + "' has a non-linear transform",
                         "resample it onto a linear (affine) transform");
    if (grid->tree().activeVoxelCount() == 0 && grid->tree().activeTileCount() == 0 &&
        grid->getGridClass() != openvdb::GRID_LEVEL_SET)
        throw InputError("grid '" + grid->getName() + "' in " + path.string() + " is empty (no active voxels)",
                         "check that the segmentation was exported with its label");
    return grid;
}

void write_vdb(const openvdb::GridBase& grid, const std::filesystem::path& path)
{
    initialize_openvdb();
    AtomicOutput out(path);
    try {
        openvdb::io::File file(out.temporary().string());
        // copyGrid shares the tree: no voxel data is duplicated.
        openvdb::GridCPtrVec grids{grid.copyGrid()};
        file.write(grids);
        file.close();
    } catch (const std::exception& e) {
        throw IoError(path.string(), std::string("cannot write the VDB file: ") + e.what());
    }
    out.commit();
}

} // namespace scalemesh
