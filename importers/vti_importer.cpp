// VTK XML ImageData (.vti), by hand like the .vtp reader (vtp_importer.cpp):
// VTK itself is about 200 MB of Debian packages for one file format, and ITK
// 5.2 as Debian ships it reads no VTK XML.

#include "importers/vti_importer.h"

#include "core/errors.h"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

namespace scalemesh {

namespace {

constexpr int64_t kMaxVoxels = int64_t{1} << 31;

std::string file_bytes(const std::filesystem::path& path)
{
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw IoError(path.string(), "no such file; check the path");
    std::ifstream file(path, std::ios::binary);
    if (!file) throw IoError(path.string(), std::string("cannot open the file: ") + std::strerror(errno));
    std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
    if (file.bad()) throw IoError(path.string(), "reading the file failed");
    return bytes;
}

class VtiReader {
public:
    VtiReader(const std::string& bytes, const std::filesystem::path& path)
        : doc_(bytes, "ImageData", path.string() + " is not a VTK ImageData image scalemesh reads: ")
    {
    }

    VtiVolume read()
    {
        const vtk_xml::Element& image = doc_.dataset();
        VtiVolume out;
        const std::vector<int64_t> extent = integers(image, "WholeExtent", 6);
        for (int d = 0; d < 3; ++d) {
            const int64_t lo = extent[2 * d], hi = extent[2 * d + 1];
            if (hi < lo)
                doc_.fail("its WholeExtent along axis " + std::to_string(d) + " runs from " + std::to_string(lo) +
                              " to " + std::to_string(hi) + ", so the image is empty",
                          "export a non-empty image");
            out.size[d] = hi - lo + 1;
        }
        int64_t voxels = 1;
        for (int d = 0; d < 3; ++d) {
            if (out.size[d] > std::numeric_limits<int>::max() || voxels * out.size[d] > kMaxVoxels)
                doc_.fail("it has " + std::to_string(out.size[0]) + " x " + std::to_string(out.size[1]) + " x " +
                              std::to_string(out.size[2]) + " voxels, more than 2^31",
                          "crop the image to the region of interest or resample it to coarser voxels");
            voxels *= out.size[d];
        }

        const std::vector<double> origin = numbers(image, "Origin", 3, {0, 0, 0});
        const std::vector<double> spacing = numbers(image, "Spacing", 3, {1, 1, 1});
        const std::vector<double> direction = numbers(image, "Direction", 9, {1, 0, 0, 0, 1, 0, 0, 0, 1});
        for (int d = 0; d < 3; ++d) {
            if (!(std::isfinite(spacing[d]) && spacing[d] > 0))
                doc_.fail("its Spacing along axis " + std::to_string(d) + " is " + std::to_string(spacing[d]) +
                              "; spacings must be positive and finite",
                          "fix the Spacing; flip an axis with Direction instead of a negative spacing");
            out.spacing[d] = spacing[d];
        }
        for (int w = 0; w < 3; ++w) {
            // The extent's first index is voxel 0 of the grid.
            double at = origin[w];
            for (int d = 0; d < 3; ++d) {
                out.direction[w][d] = direction[3 * w + d];
                at += direction[3 * w + d] * spacing[d] * static_cast<double>(extent[2 * d]);
            }
            if (!std::isfinite(at)) doc_.fail("its Origin or Direction is not finite", "fix the image's geometry");
            out.origin[w] = at;
        }

        std::vector<const vtk_xml::Element*> pieces;
        for (const vtk_xml::Element& e : image.children)
            if (e.name == "Piece") pieces.push_back(&e);
        if (pieces.size() != 1)
            doc_.fail("it has " + std::to_string(pieces.size()) + " pieces; scalemesh reads an image in one piece",
                      "save the image as one piece (ParaView: Merge Blocks, or vtkXMLImageDataWriter on the whole "
                      "extent)");
        const vtk_xml::Element& piece = *pieces.front();
        if (!piece.attribute("Extent").empty() && integers(piece, "Extent", 6) != extent)
            doc_.fail("its piece's Extent is not its WholeExtent", "save the image as one piece");

        const vtk_xml::Element* scalars = point_scalars(piece);
        vtk_xml::Array values = doc_.read(*scalars, "its point data '" + scalars->attribute("Name") + "'",
                                          static_cast<uint64_t>(voxels));
        if (values.components != 1)
            doc_.fail("its point data '" + values.name + "' have " + std::to_string(values.components) +
                          " components per voxel",
                      "give a label map, an intensity image or a level set with one value per voxel");
        out.type = values.type;
        out.data = std::move(values.data);
        return out;
    }

private:
    const vtk_xml::Element* point_scalars(const vtk_xml::Element& piece)
    {
        const vtk_xml::Element* points = piece.child("PointData");
        if (points) {
            const std::string wanted = points->attribute("Scalars");
            if (!wanted.empty()) {
                for (const vtk_xml::Element& e : points->children)
                    if (e.name == "DataArray" && e.attribute("Name") == wanted) return &e;
                doc_.fail("its PointData names Scalars=\"" + wanted + "\", but holds no array of that name");
            }
            if (const vtk_xml::Element* first = points->child("DataArray")) return first;
        }
        const vtk_xml::Element* cells = piece.child("CellData");
        if (cells && cells->child("DataArray"))
            doc_.fail("its values are cell data, one per cell between the points, not point data",
                      "convert them to point data (ParaView: Cell Data to Point Data) or resample the image");
        doc_.fail("its piece has no point data array", "export the image with its scalars");
    }

    std::string text(const vtk_xml::Element& e, const std::string& key, size_t n)
    {
        const std::string t = e.attribute(key);
        if (t.empty()) doc_.fail("its <" + e.name + "> has no " + key + " (" + std::to_string(n) + " numbers)");
        return t;
    }

    std::vector<int64_t> integers(const vtk_xml::Element& e, const std::string& key, size_t n)
    {
        const std::string t = text(e, key, n);
        std::vector<int64_t> out;
        std::istringstream in(t);
        for (std::string word; in >> word;) {
            int64_t v = 0;
            const auto [end, error] = std::from_chars(word.data(), word.data() + word.size(), v);
            if (error != std::errc() || end != word.data() + word.size() || std::abs(v) > (int64_t{1} << 40))
                doc_.fail("its " + key + " holds '" + word.substr(0, 40) + "', not an index");
            out.push_back(v);
        }
        if (out.size() != n)
            doc_.fail("its " + key + " has " + std::to_string(out.size()) + " numbers instead of " + std::to_string(n));
        return out;
    }

    std::vector<double> numbers(const vtk_xml::Element& e, const std::string& key, size_t n,
                                std::vector<double> fallback)
    {
        if (e.attribute(key).empty()) return fallback;
        const std::string t = e.attribute(key);
        std::vector<double> out;
        std::istringstream in(t);
        for (std::string word; in >> word;) {
            std::string_view w = word;
            if (w.front() == '+') w.remove_prefix(1);
            double v = 0;
            const auto [end, error] = std::from_chars(w.data(), w.data() + w.size(), v);
            if (error != std::errc() || end != w.data() + w.size() || !std::isfinite(v))
                doc_.fail("its " + key + " holds '" + word.substr(0, 40) + "', not a finite number",
                          "fix the image's geometry");
            out.push_back(v);
        }
        if (out.size() != n)
            doc_.fail("its " + key + " has " + std::to_string(out.size()) + " numbers instead of " + std::to_string(n));
        return out;
    }

    vtk_xml::Document doc_;
};

} // namespace

VtiVolume read_vti_volume(const std::filesystem::path& path)
{
    const std::string bytes = file_bytes(path);
    return VtiReader(bytes, path).read();
}

} // namespace scalemesh
