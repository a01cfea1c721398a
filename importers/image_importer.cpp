#include "importers/image_importer.h"

#include "core/errors.h"
#include "core/memory_text.h"
#include "importers/vti_importer.h"

#include <itkImageIOBase.h>
#include <itkMetaImageIO.h>
#include <itkNiftiImageIO.h>
#include <itkNrrdImageIO.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <zlib.h>

#include <algorithm>
#include <cstdio>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <string_view>
#include <type_traits>

namespace scalemesh {

namespace {

using Leaf = openvdb::FloatTree::LeafNodeType;
constexpr int64_t kLeafDim = Leaf::DIM; // 8
constexpr int64_t kMaxVoxels = int64_t{1} << 31;

enum class Format { Nifti, Nrrd, MetaImage, Vti };

struct Extension {
    const char* suffix;
    Format format;
};
// Longest suffix first, so that ".nii.gz" is not taken for ".gz".
constexpr Extension kExtensions[] = {{".nii.gz", Format::Nifti}, {".nii", Format::Nifti},
                                     {".nrrd", Format::Nrrd},    {".nhdr", Format::Nrrd},
                                     {".mha", Format::MetaImage}, {".mhd", Format::MetaImage},
                                     {".vti", Format::Vti}};
constexpr const char* kSupported = ".nii, .nii.gz, .nrrd, .nhdr, .mha, .mhd, .vti";

const char* format_name(Format f)
{
    switch (f) {
    case Format::Nifti: return "NIfTI";
    case Format::Nrrd: return "NRRD";
    case Format::MetaImage: return "MetaImage";
    case Format::Vti: return "VTK ImageData";
    }
    return "image";
}

std::optional<Format> format_of(const std::filesystem::path& path)
{
    std::string name = path.filename().string();
    std::transform(name.begin(), name.end(), name.begin(), [](unsigned char c) { return std::tolower(c); });
    for (const Extension& e : kExtensions)
        if (name.size() > std::string_view(e.suffix).size() && name.ends_with(e.suffix)) return e.format;
    return std::nullopt;
}

// ITK's MetaIO and its warning macros write to std::cerr, and the library
// never prints; what they write is kept and added to the error message.
class CerrCapture {
public:
    CerrCapture() : previous_(std::cerr.rdbuf(text_.rdbuf())) {}
    ~CerrCapture() { std::cerr.rdbuf(previous_); }
    CerrCapture(const CerrCapture&) = delete;
    CerrCapture& operator=(const CerrCapture&) = delete;
    std::string text() const { return text_.str(); }

private:
    std::ostringstream text_;
    std::streambuf* previous_;
};

// Error text on one line, at most `limit` characters, without ITK's
// "ITK ERROR: Class(0x...): " prefixes (an object address means nothing to a
// user) and, for NRRD, only the innermost of teem's chained messages
// ("[nrrd] nrrdLoad: trouble ... [nrrd] _nrrdEncodingRaw_read: fread got only
// 125 4-sized things"), which is the one that names the fault.
std::string one_line(std::string text, size_t limit = 240)
{
    for (const char* prefix : {"ITK ERROR: ", "itk::ERROR: "})
        for (size_t at; (at = text.find(prefix)) != std::string::npos;) {
            const size_t close = text.find("): ", at);
            text.erase(at, close == std::string::npos ? std::string_view(prefix).size() : close + 3 - at);
        }
    if (const size_t teem = text.rfind("[nrrd] "); teem != std::string::npos) text = text.substr(teem + 7);
    std::string out;
    for (char c : text) {
        const bool space = std::isspace(static_cast<unsigned char>(c)) || !std::isprint(static_cast<unsigned char>(c));
        if (space) {
            if (!out.empty() && out.back() != ' ') out += ' ';
        } else {
            out += c;
        }
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    if (out.size() > limit) out = out.substr(0, limit - 3) + "...";
    return out;
}

std::string number(double v)
{
    std::ostringstream out;
    if (std::abs(v) < 1e15 && v == std::floor(v)) out << static_cast<int64_t>(v);
    else out << v;
    return out.str();
}

std::string size_text(const std::vector<int64_t>& size)
{
    std::string out;
    for (size_t i = 0; i < size.size(); ++i) out += (i ? " x " : "") + std::to_string(size[i]);
    return out;
}

void throw_too_many_voxels(const std::string& name, const std::string& size)
{
    throw InputError(name + " has " + size + " voxels, more than 2^31",
                     "crop the image to the region of interest or resample it to coarser voxels");
}

// Bytes per voxel of NIfTI-1's scalar datatypes; 0 for the others.
int nifti_scalar_bytes(int datatype)
{
    switch (datatype) {
    case 2: case 256: return 1;    // uint8, int8
    case 4: case 512: return 2;    // int16, uint16
    case 8: case 16: case 768: return 4; // int32, float32, uint32
    case 64: case 1024: case 1280: return 8; // float64, int64, uint64
    default: return 0;
    }
}

// ITK 5.2's NIfTI reader fills voxels missing from a truncated file with
// zeros, turns a zero or negative size into 1, replaces a zero or NaN pixdim
// by 1, and lets nifti1_io print header errors to stderr. So the NIfTI-1
// header is checked here first, and the data length counted (for .nii.gz at
// the cost of inflating the file once more).
// The import holds the voxels as read (component_bytes each) and the grid
// made of them (a float each, for a level set): refused before any voxel is
// read, or inflated, when that is more than `max_bytes` (0: no bound).
void require_image_memory(const std::string& name, double voxels, int component_bytes, int64_t max_bytes)
{
    const double needed = voxels * (component_bytes + sizeof(float));
    if (max_bytes <= 0 || needed <= static_cast<double>(max_bytes)) return;
    throw InputError(name + " holds " + number(voxels) + " voxels of " + std::to_string(component_bytes) +
                         " bytes, which would take about " + memory_text(needed) + " to import, more than the " +
                         memory_text(static_cast<double>(max_bytes)) + " allowed",
                     "crop the image to the region of interest (or resample it coarser), or raise --max-memory on "
                     "a machine with more memory");
}

void check_nifti(const std::filesystem::path& path, int64_t max_bytes)
{
    const std::string name = path.string();
    const std::string hint = "the file may be truncated or corrupt; re-export it";
    gzFile file = gzopen(name.c_str(), "rb");
    if (!file) throw IoError(name, "cannot be opened for reading; check its permissions");
    const std::unique_ptr<gzFile_s, int (*)(gzFile)> closer(file, gzclose);

    std::array<char, 348> h{};
    const int got = gzread(file, h.data(), static_cast<unsigned>(h.size()));
    if (got < static_cast<int>(h.size()))
        throw InputError(name + " is not a NIfTI file: " +
                             (got < 0 ? std::string("its compressed data are corrupt")
                                      : "it is shorter than a NIfTI-1 header (" + std::to_string(got) +
                                            " of 348 bytes)"),
                         hint);
    bool swap = false;
    auto load = [&h, &swap]<typename T>(size_t offset, T) {
        std::array<char, sizeof(T)> b;
        std::copy_n(h.begin() + static_cast<std::ptrdiff_t>(offset), sizeof(T), b.begin());
        if (swap) std::reverse(b.begin(), b.end());
        return std::bit_cast<T>(b);
    };
    const int32_t header_size = load(0, int32_t{});
    if (header_size != 348) {
        swap = true;
        if (load(0, int32_t{}) != 348) {
            swap = false;
            if (header_size == 540 || load(0, int32_t{}) == 540)
                throw InputError(name + " is a NIfTI-2 file, which ITK 5.2 does not read", "save it as NIfTI-1");
            throw InputError(name + " is not a NIfTI-1 file (wrong header size field)", hint);
        }
    }
    if (std::string_view(h.data() + 344, 4) != std::string_view("n+1\0", 4))
        throw InputError(name + " is not a single-file NIfTI-1 file (wrong magic number, 'n+1' expected)", hint);

    const int rank = load(40, int16_t{});
    if (rank < 1 || rank > 7)
        throw InputError(name + " has an invalid number of dimensions (dim[0] = " + std::to_string(rank) + ")", hint);
    std::vector<int64_t> size;
    double voxels = 1;
    for (int d = 1; d <= rank; ++d) {
        size.push_back(load(40 + 2 * static_cast<size_t>(d), int16_t{}));
        voxels *= static_cast<double>(size.back());
    }
    if (*std::min_element(size.begin(), size.end()) < 1)
        throw InputError(name + " has a zero or negative size (" + size_text(size) + " voxels)",
                         "the header is corrupt or the image is empty; re-export it");
    if (voxels > static_cast<double>(kMaxVoxels)) throw_too_many_voxels(name, size_text(size));

    const int datatype = load(70, int16_t{});
    const int bytes = nifti_scalar_bytes(datatype);
    if (bytes == 0)
        throw InputError(name + " has NIfTI datatype " + std::to_string(datatype) +
                             ", not an integer or floating-point scalar",
                         "give a label map, an intensity image or a level set with one number per voxel");
    require_image_memory(name, voxels, bytes, max_bytes);
    for (int d = 1; d <= std::min(rank, 3); ++d) {
        const float spacing = load(76 + 4 * static_cast<size_t>(d), float{});
        if (!std::isfinite(spacing) || spacing == 0 || std::abs(spacing) > 1e9f)
            throw InputError(name + " has voxel spacing pixdim[" + std::to_string(d) + "] = " + number(spacing),
                             "fix the spacing in the header");
    }
    // ITK takes the orientation from the qform or the sform, whichever is set,
    // through an SVD that aborts the process on a NaN or infinite entry (vnl's
    // assert_finite) and never returns on an sform offset of -1.7e38 (found
    // by fuzzing). No scanner places an image a million kilometres away:
    // entries are held to 1e9 (mm, or the rotation times the spacing).
    const auto require_finite = [&](size_t offset, int count, const char* what) {
        for (int i = 0; i < count; ++i) {
            const float value = load(offset + 4 * static_cast<size_t>(i), float{});
            if (!std::isfinite(value))
                throw InputError(name + " has a NaN or infinite entry in its " + what,
                                 "fix the orientation in the header");
            if (std::abs(value) > 1e9f)
                throw InputError(name + " has an entry of " + number(value) + " in its " + what +
                                     ", beyond 1e9 in magnitude",
                                 "fix the orientation in the header");
        }
    };
    if (load(252, int16_t{}) > 0) require_finite(256, 6, "qform (quatern_b, c, d, qoffset)");
    if (load(254, int16_t{}) > 0) require_finite(280, 12, "sform (srow_x, srow_y, srow_z)");
    const float vox_offset = load(108, float{});
    if (!std::isfinite(vox_offset) || vox_offset < 0 || vox_offset > 1e9f)
        throw InputError(name + " has an invalid data offset (vox_offset = " + number(vox_offset) + ")", hint);

    // nifti1_io reads the data from max(vox_offset, 348).
    const int64_t needed = std::max<int64_t>(348, static_cast<int64_t>(vox_offset)) +
                           static_cast<int64_t>(voxels) * bytes;
    int64_t length = 0;
    if (gzdirect(file)) {
        std::error_code ec;
        length = static_cast<int64_t>(std::filesystem::file_size(path, ec));
    } else {
        length = got;
        std::vector<char> buffer(1 << 18);
        for (int n; (n = gzread(file, buffer.data(), static_cast<unsigned>(buffer.size()))) != 0;) {
            if (n < 0) {
                int code = 0;
                throw InputError(name + " has corrupt compressed data (" + std::string(gzerror(file, &code)) + ")",
                                 hint);
            }
            length += n;
            if (length >= needed) break;
        }
    }
    if (length < needed)
        throw InputError(name + " is truncated: its header promises " + std::to_string(needed) +
                             " bytes, the file holds " + std::to_string(length),
                         hint);
}

// The key of a MetaImage header line as MetaIO's MET_Read takes it: from the
// first non-blank character to the first '=', ':' or '\r' (or the line's end),
// trailing blanks removed; and the value after the first '=' or ':', trimmed.
std::pair<std::string, std::optional<std::string>> metaimage_field(const std::string& line)
{
    const auto trim = [](const std::string& text) {
        const size_t first = text.find_first_not_of(" \t\r");
        return first == std::string::npos ? std::string()
                                          : text.substr(first, text.find_last_not_of(" \t\r") + 1 - first);
    };
    // MetaIO holds the key as a C string: it ends at a NUL byte too (found by
    // fuzzing: "CompressedData" then NULs then ": = True" is compressed to
    // MetaIO, and its inflate of the data never ended).
    const std::string head = line.substr(0, line.find_first_of("=:\r"));
    const std::string key = trim(head.substr(0, head.find('\0')));
    const size_t separator = line.find_first_of("=:");
    if (separator == std::string::npos) return {key, std::nullopt};
    // MetaIO's MET_SkipToVal skips every '=', ':' and blank after the key, so
    // "CompressedData: = True" is true to it (found by fuzzing: read as
    // "= True" here, the compressed data went unchecked and MetaIO's inflate
    // never ended).
    const size_t value = line.find_first_not_of("=: \t\r", separator);
    if (value == std::string::npos) return {key, std::string()};
    return {key, trim(line.substr(value))};
}

// Checks of a MetaImage header that ITK 5.2's MetaIO does not make, up to the
// ElementDataFile line that ends the header (found by fuzzing, fuzz/regressions/
// metaimage):
// - MetaIO does not read a header line by line: after a key it skips to the
//   next '=' or ':', across line ends, and takes what follows as the value.
//   A line without a separator, or with nothing after it, makes the next line
//   its value; when that line is ElementDataFile, the voxels that follow are
//   read as more header. So every non-blank line up to ElementDataFile must be
//   "key = value" with a key and a value, and the checks below then see the
//   lines MetaIO sees.
// - MetaIO copies every key (the text up to '=', ':' or the end of the line,
//   up to 500 characters) into a field name of 255 characters with strcpy: a
//   longer key overflows it; no run of characters between separators may be
//   that long.
// - For compressed data it allocates and reads CompressedDataSize bytes, as
//   many as the header says, and inflates them; a zlib stream that asks for a
//   preset dictionary makes its MET_PerformUncompression loop forever
//   (inflate returns Z_NEED_DICT, which it takes for progress). So
//   CompressedDataSize must be a positive integer no larger than the data
//   that follow the header (or the data file), and the stream must not ask
//   for a dictionary.
// - Each field that has one value per dimension (DimSize, ElementSpacing,
//   Offset, TransformMatrix with NDims x NDims) is read as NDims numbers cast
//   to int, into a buffer of MET_MAX_NUMBER_OF_FIELD_VALUES: an NDims beyond
//   int makes it read for hours, one beyond 64 overflows the buffer with the
//   matrix. So NDims, read as MetaIO reads it (a double), must lie in
//   [1, 64].
constexpr int kMaxMetaImageDims = 64; // 64 x 64 = MET_MAX_NUMBER_OF_FIELD_VALUES

void check_metaimage(const std::filesystem::path& path)
{
    const std::string name = path.string();
    const std::string hint = "the header is corrupt, or the file is not a MetaImage; re-export it";
    std::ifstream in(path, std::ios::binary);
    bool compressed = false;
    std::optional<std::string> compressed_size;
    for (std::string line; std::getline(in, line);) {
        size_t run = 0;
        for (const char c : line) {
            run = c == '=' || c == ':' || c == '\r' ? 0 : run + 1;
            if (run >= MET_MAX_NAME_SIZE)
                throw InputError(name + " is not a MetaImage file: its header has a key of more than " +
                                     std::to_string(MET_MAX_NAME_SIZE - 1) + " characters",
                                 hint);
        }
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        const auto [key, value] = metaimage_field(line);
        if (key.empty() || !value || value->empty())
            throw InputError(name + " has a header line '" + one_line(line, 40) +
                                 "' that is not 'key = value'",
                             hint);
        // MetaIO takes a value beginning with T, t or 1 for true.
        if (key == "CompressedData")
            compressed = !value->empty() && std::string_view("Tt1").find(value->front()) != std::string_view::npos;
        if (key == "CompressedDataSize") compressed_size = value;
        if (key == "NDims" && value) {
            std::istringstream number(*value);
            double dims = 0;
            if (number >> dims && !(dims >= 1 && dims < kMaxMetaImageDims + 1))
                throw InputError(name + " has NDims = '" + value->substr(0, 40) + "'; a MetaImage has 1 to " +
                                     std::to_string(kMaxMetaImageDims) + " dimensions (3 for a volume)",
                                 hint);
        }
        if (key != "ElementDataFile") continue;

        // A pattern of slice files, "name%03d.raw first last step": MetaIO
        // divides by the step it reads with atoi, so a missing or zero step
        // ends the process with a division by zero (found by fuzzing).
        if (value->find('%') != std::string::npos) {
            std::istringstream words(*value);
            std::string pattern, first, last, step, extra;
            words >> pattern >> first >> last >> step;
            const auto integer = [](const std::string& w) {
                const size_t digits = w.find_first_not_of("0123456789", w.starts_with('-') ? 1 : 0);
                return !w.empty() && w != "-" && w.size() < 10 && digits == std::string::npos;
            };
            if (words >> extra || !integer(first) || !integer(last) || !integer(step) || std::stoi(step) <= 0 ||
                std::stoi(last) < std::stoi(first))
                throw InputError(name + " names its data as a file pattern ('" + value->substr(0, 60) +
                                     "') without a first and last number and a positive step",
                                 "write ElementDataFile = name%03d.raw FIRST LAST STEP, or save the image as one .mha");
        }
        if (!compressed) return;
        if (!compressed_size)
            throw InputError(name + " has compressed data but no CompressedDataSize in its header", hint);
        const std::string& text = *compressed_size;
        if (text.empty() || text.size() > 15 || text.find_first_not_of("0123456789") != std::string::npos ||
            std::stoll(text) == 0)
            throw InputError(name + " has CompressedDataSize = '" + text.substr(0, 40) +
                                 "', not a positive whole number of bytes",
                             hint);
        const int64_t size = std::stoll(text);
        std::filesystem::path data_path = path;
        std::error_code ec;
        const auto header_size = std::filesystem::file_size(path, ec);
        if (ec) return;
        // At the end of the file (no newline after the line) tellg fails: no data follow.
        int64_t data_offset = in.tellg() < 0 ? static_cast<int64_t>(header_size) : static_cast<int64_t>(in.tellg());
        if (*value != "LOCAL") {
            if (value->starts_with("LIST") || value->find_first_of("% \t") != std::string::npos)
                throw InputError(name + " has compressed data in a list or pattern of files, which is not read",
                                 "save the image as one .mha file or one .mhd with one data file");
            data_path = path.parent_path() / *value;
            data_offset = 0;
        }
        const auto file_size = std::filesystem::file_size(data_path, ec);
        if (ec) return; // ITK reports the missing data file
        const int64_t available = std::max<int64_t>(0, static_cast<int64_t>(file_size) - data_offset);
        if (size > available)
            throw InputError(name + " is truncated or its header is corrupt: CompressedDataSize is " + text +
                                 " bytes, but " + (*value == "LOCAL" ? "only " + std::to_string(available) +
                                                                             " bytes of data follow the header"
                                                                       : data_path.string() + " holds " +
                                                                             std::to_string(available) + " bytes"),
                             "the file may be truncated or corrupt; re-export it");
        // A zlib header (RFC 1950): compression method 8, a multiple of 31,
        // and FDICT (bit 5 of the second byte) for a preset dictionary.
        std::array<unsigned char, 2> head{};
        std::ifstream data(data_path, std::ios::binary);
        data.seekg(data_offset);
        data.read(reinterpret_cast<char*>(head.data()), 2);
        if (data && (head[0] & 0x0f) == 8 && (head[0] * 256 + head[1]) % 31 == 0 && (head[1] & 0x20) != 0)
            throw InputError(name + " has compressed data that ask for a preset zlib dictionary, which MetaImage "
                                    "files do not carry",
                             "the file may be truncated or corrupt; re-export it");
        return;
    }
}

// What a reader read (ITK, or the .vti reader): geometry in double precision
// and the raw voxel buffer in the file's component type (x fastest, then y,
// then z).
struct RawImage {
    std::array<int64_t, 3> size{};
    std::array<double, 3> spacing{};
    std::array<double, 3> origin{};
    std::array<std::array<double, 3>, 3> direction{}; // direction[world axis][index axis]
    itk::IOComponentEnum component = itk::IOComponentEnum::UNKNOWNCOMPONENTTYPE;
    std::unique_ptr<char[]> data;
    int64_t voxels() const { return size[0] * size[1] * size[2]; }
};

itk::ImageIOBase::Pointer make_io(Format format)
{
    // The reader is chosen by extension rather than through ITK's factories:
    // no registration is needed, and a file is only ever parsed by the reader
    // its name promises.
    switch (format) {
    case Format::Nifti: {
        auto io = itk::NiftiImageIO::New();
        // A .nii without NIfTI's magic would otherwise be read as Analyze 7.5,
        // whose orientation is ill-defined.
        io->SetLegacyAnalyze75Mode(itk::NiftiImageIOEnums::Analyze75Flavor::AnalyzeReject);
        return io;
    }
    case Format::Nrrd: return itk::NrrdImageIO::New().GetPointer();
    case Format::MetaImage: return itk::MetaImageIO::New().GetPointer();
    case Format::Vti: break; // read without ITK (vti_importer.h)
    }
    return nullptr;
}

// ITK's NIfTI reader keeps a static string in ReadImageInformation, and
// std::cerr is swapped while MetaIO reads: one read at a time. ITK's NIfTI
// reader sets nifti1_io's process-wide debug level to 0 itself, and
// nifti1_io has no way to read a level back, so it cannot be restored
// (include/scalemesh/mesh.h says so).
std::mutex g_itk_mutex;

void read_header(itk::ImageIOBase& io, const std::string& name, Format format, RawImage& image)
{
    if (!io.CanReadFile(name.c_str()))
        throw InputError(name + " is not a " + std::string(format_name(format)) +
                             " file (its header is not recognised: wrong magic number or corrupt header)",
                         "check that the file is complete and its extension matches its format");
    io.SetFileName(name);
    io.ReadImageInformation();

    const unsigned dims = io.GetNumberOfDimensions();
    std::vector<int64_t> size(dims);
    for (unsigned d = 0; d < dims; ++d) size[d] = static_cast<int64_t>(io.GetDimensions(d));
    if (std::find(size.begin(), size.end(), 0) != size.end())
        throw InputError(name + " has a zero size (" + size_text(size) + " voxels)",
                         "the header is corrupt or the image is empty; re-export it");
    if (dims < 3)
        throw InputError(name + " is a " + std::to_string(dims) + "D image (" + size_text(size) +
                             " voxels); a 3D volume is needed",
                         "stack the slices into one 3D volume");
    for (unsigned d = 3; d < dims; ++d)
        if (size[d] != 1)
            throw InputError(name + " is a " + std::to_string(dims) + "D image (" + size_text(size) +
                                 " voxels) holding more than one 3D volume",
                             "extract the one volume to mesh into its own file");
    if (io.GetNumberOfComponents() != 1 || io.GetPixelType() != itk::IOPixelEnum::SCALAR)
        throw InputError(name + " has " + std::to_string(io.GetNumberOfComponents()) + " components per voxel (" +
                             itk::ImageIOBase::GetPixelTypeAsString(io.GetPixelType()) + "), not a scalar image",
                         "give a label map, an intensity image or a level set with one value per voxel");

    // Overflow-free: both factors are at most 2^31. Each size also fits the int
    // of an OpenVDB coordinate.
    int64_t voxels = 1;
    for (int d = 0; d < 3; ++d) {
        if (size[d] > std::numeric_limits<int>::max() || voxels * size[d] > kMaxVoxels)
            throw_too_many_voxels(name, size_text(size));
        voxels *= size[d];
        image.size[d] = size[d];
    }

    for (int d = 0; d < 3; ++d) {
        image.spacing[d] = io.GetSpacing(d);
        image.origin[d] = io.GetOrigin(d);
        const std::vector<double> axis = io.GetDirection(d);
        for (int w = 0; w < 3; ++w) image.direction[w][d] = axis.at(w);
    }
    image.component = io.GetComponentType();

    // MetaIO parses text voxels without noticing when they run out, so a
    // truncated text file would be read as a complete one.
    if (auto* meta = dynamic_cast<itk::MetaImageIO*>(&io); meta && !meta->GetMetaImagePointer()->BinaryData())
        throw InputError(name + " stores its voxels as text (BinaryData = False), which is not read",
                         "save the MetaImage with binary data");
}

// zlib's deflate, the one compression these readers take, packs at most 1032
// bytes into one; no other encoding of theirs is denser.
constexpr int64_t kMaxCompressionRatio = 1032;

std::optional<int64_t> size_of(const std::filesystem::path& path)
{
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(path, ec);
    if (ec) return std::nullopt;
    return static_cast<int64_t>(bytes);
}

// The size of the file holding the voxels: the header's own file when the
// data are attached (NRRD without "data file", MetaImage "LOCAL"), else the
// one data file it names; nullopt for a list or pattern of files, left to ITK.
std::optional<int64_t> data_file_size(itk::ImageIOBase& io, const std::filesystem::path& path)
{
    std::string data_file;
    if (auto* meta = dynamic_cast<itk::MetaImageIO*>(&io)) {
        data_file = meta->GetMetaImagePointer()->ElementDataFileName();
        if (data_file == "LOCAL") data_file.clear();
    } else if (dynamic_cast<itk::NrrdImageIO*>(&io)) {
        // The header runs to the first empty line; ITK does not tell the data file.
        std::ifstream in(path, std::ios::binary);
        for (std::string line; std::getline(in, line) && !line.empty() && line != "\r";) {
            for (const std::string_view key : {"data file:", "datafile:"})
                if (line.starts_with(key)) data_file = line.substr(key.size());
        }
        const auto first = data_file.find_first_not_of(" \t");
        const auto last = data_file.find_last_not_of(" \t\r");
        data_file = first == std::string::npos ? "" : data_file.substr(first, last + 1 - first);
    } else {
        return std::nullopt; // NIfTI: check_nifti counts its data
    }
    if (data_file.empty()) return size_of(path);
    if (data_file.starts_with("LIST") || data_file.find_first_of("% \t") != std::string::npos) return std::nullopt;
    // A device (/dev/zero) or a FIFO would be read without end or wait
    // forever: only a regular file holds voxels.
    // operator/ keeps an absolute data file as it is.
    const std::filesystem::path data = path.parent_path() / data_file;
    std::error_code ec;
    const std::filesystem::file_status status = std::filesystem::status(data, ec);
    if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status))
        throw InputError(path.string() + " names " + data.string() + " as its data file, which is not a regular file "
                                         "(a device, a FIFO or a directory)",
                         "point the header at the file holding the voxels");
    return size_of(data);
}

// A corrupt header can promise gigabytes of voxels in a file of a few bytes:
// refused before the buffer for them is allocated.
void check_data_size(itk::ImageIOBase& io, const RawImage& image, const std::filesystem::path& path)
{
    const std::optional<int64_t> bytes = data_file_size(io, path);
    const auto needed = image.voxels() * static_cast<int64_t>(io.GetComponentSize());
    if (bytes && needed / kMaxCompressionRatio > *bytes)
        throw InputError(path.string() + " is truncated or its header is corrupt: " + std::to_string(image.voxels()) +
                             " voxels (" + std::to_string(needed) + " bytes) cannot come from " +
                             std::to_string(*bytes) + " bytes of data, even compressed",
                         "the file may be truncated or corrupt; re-export it");
}

// The last bytes of the buffer before the read: a fixed random pattern. ITK
// 5.2's MetaImage reader does not check that compressed data inflate to the
// whole image, and leaves the rest of the buffer as it was; a read that leaves
// the pattern in place therefore stopped short. Real data ending in these 16
// bytes are a 2^-128 chance; a file missing fewer than 16 bytes of its last
// voxels is not detected this way.
constexpr std::array<unsigned char, 16> kTailPattern{0x5f, 0xc3, 0x1e, 0x9a, 0x44, 0xd7, 0x02, 0xb8,
                                                     0x6d, 0xf1, 0x39, 0x80, 0xae, 0x17, 0xe5, 0x4b};

void read_voxels(itk::ImageIOBase& io, RawImage& image, const std::string& name)
{
    const unsigned dims = io.GetNumberOfDimensions();
    itk::ImageIORegion region(dims);
    for (unsigned d = 0; d < dims; ++d) {
        region.SetIndex(d, 0);
        region.SetSize(d, io.GetDimensions(d));
    }
    io.SetIORegion(region);
    const size_t bytes = static_cast<size_t>(image.voxels()) * io.GetComponentSize();
    // Not value-initialised: a corrupt header claiming far more voxels than
    // the file holds then costs address space, not memory, before the read fails.
    image.data.reset(new char[bytes]);
    const size_t tail = std::min(bytes, kTailPattern.size());
    char* end = image.data.get() + bytes;
    std::memcpy(end - tail, kTailPattern.data() + kTailPattern.size() - tail, tail);
    io.Read(image.data.get());
    if (std::memcmp(end - tail, kTailPattern.data() + kTailPattern.size() - tail, tail) == 0)
        throw InputError(name + " is truncated: its data end before the last voxel",
                         "the file may be truncated or corrupt; re-export it");
}

RawImage read_with_itk(const std::filesystem::path& path, Format format, int64_t max_bytes)
{
    std::lock_guard<std::mutex> lock(g_itk_mutex);
    const std::string name = path.string();
    const std::string as = std::string(" could not be read as ") + format_name(format) + ": ";
    const std::string hint = "the file may be truncated or corrupt; re-export it";
    // Only MetaIO reports on std::cerr what it does not throw; the other
    // formats' readers leave the host's std::cerr alone.
    std::optional<CerrCapture> captured;
    if (format == Format::MetaImage) captured.emplace();
    const auto said = [&] { return captured ? captured->text() : std::string(); };
    RawImage image;
    try {
        itk::ImageIOBase::Pointer io = make_io(format);
        read_header(*io, name, format, image);
        require_image_memory(name, static_cast<double>(image.voxels()), static_cast<int>(io->GetComponentSize()),
                             max_bytes);
        check_data_size(*io, image, path);
        const size_t said_before = said().size();
        read_voxels(*io, image, name);
        // MetaIO reports some failures only on std::cerr ("data not read
        // completely" for compressed data cut short) and still returns success.
        if (said().size() > said_before) throw InputError(name + as + one_line(said().substr(said_before)), hint);
    } catch (const Error&) {
        throw;
    } catch (const itk::ExceptionObject& e) {
        std::string reason = one_line(e.GetDescription());
        const std::string also = one_line(said(), 160);
        if (!also.empty()) reason += " (" + also + ")";
        throw InputError(name + as + reason, hint);
    } catch (const std::bad_alloc&) {
        throw InputError(name + " needs more memory than is available for its " + std::to_string(image.voxels()) +
                             " voxels",
                         "crop the image to the region of interest or resample it to coarser voxels");
    } catch (const std::exception& e) {
        throw InputError(name + as + one_line(e.what()), hint);
    }
    return image;
}

// The image-to-world map as an OpenVDB transform. OpenVDB multiplies row
// vectors, so row i of the matrix is index axis i's step in world space.
openvdb::math::Transform::Ptr image_transform(const RawImage& image, const std::string& name)
{
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    for (int d = 0; d < 3; ++d) {
        if (!std::isfinite(image.spacing[d]) || image.spacing[d] <= 0)
            throw InputError(name + " has voxel spacing " + number(image.spacing[d]) + " along axis " +
                                 std::to_string(d) + "; spacings must be positive",
                             "fix the spacing in the header (NIfTI pixdim, NRRD space directions, MetaImage "
                             "ElementSpacing)");
        if (!std::isfinite(image.origin[d]))
            throw InputError(name + " has a non-finite origin", "fix the origin in the header");
        for (int w = 0; w < 3; ++w) {
            if (!std::isfinite(image.direction[w][d]))
                throw InputError(name + " has a non-finite direction matrix", "fix the direction in the header");
            m(d, w) = image.direction[w][d] * image.spacing[d];
        }
        m(3, d) = image.origin[d];
    }
    const auto& r = image.direction;
    const double det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) -
                       r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                       r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    if (!(std::abs(det) > 1e-6))
        throw InputError(name + " has a singular direction matrix (determinant " + number(det) + ")",
                         "fix the orientation in the header: its three axes must be independent");
    try {
        return openvdb::math::Transform::createLinearTransform(m);
    } catch (const openvdb::Exception&) {
        // OpenVDB refuses a determinant below 3e-15 in absolute terms: voxels
        // narrower than about 10 nm in millimetre units.
        throw InputError(name + " has voxels too small for an invertible transform (spacing " +
                             number(image.spacing[0]) + " x " + number(image.spacing[1]) + " x " +
                             number(image.spacing[2]) + ")",
                         "give the spacing in millimetres");
    }
}

// Range and non-finite values, in one parallel pass.
struct Stats {
    double min = std::numeric_limits<double>::infinity();
    double max = -std::numeric_limits<double>::infinity();
    int64_t nonfinite = 0;
    int64_t first_nonfinite = std::numeric_limits<int64_t>::max(); // linear index

    void join(const Stats& o)
    {
        min = std::min(min, o.min);
        max = std::max(max, o.max);
        nonfinite += o.nonfinite;
        first_nonfinite = std::min(first_nonfinite, o.first_nonfinite);
    }
};

template <typename T>
Stats value_stats(const T* values, int64_t count)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<int64_t>(0, count, 1 << 16), Stats{},
        [values](const tbb::blocked_range<int64_t>& r, Stats s) {
            for (int64_t i = r.begin(); i != r.end(); ++i) {
                const double v = static_cast<double>(values[i]);
                if constexpr (std::is_floating_point_v<T>) {
                    if (!std::isfinite(v)) {
                        ++s.nonfinite;
                        s.first_nonfinite = std::min(s.first_nonfinite, i);
                        continue;
                    }
                }
                s.min = std::min(s.min, v);
                s.max = std::max(s.max, v);
            }
            return s;
        },
        [](Stats a, const Stats& b) {
            a.join(b);
            return a;
        });
}

// The smallest `limit` distinct values, and whether there are more; for error
// messages only.
template <typename T>
std::string present_values(const T* values, int64_t count, size_t limit = 10)
{
    std::set<double> smallest;
    bool more = false;
    for (int64_t i = 0; i < count; ++i) {
        smallest.insert(static_cast<double>(values[i]));
        if (smallest.size() > limit) {
            smallest.erase(std::prev(smallest.end()));
            more = true;
        }
    }
    std::string out;
    for (double v : smallest) out += (out.empty() ? "" : ", ") + number(v);
    return out + (more ? ", ..." : "");
}

// Leaves built block by block, in parallel, then added to the tree: a tree's
// setValue per voxel would be far slower on large images. `voxel` maps a
// value to the grid value of an active voxel, or nullopt for background.
template <typename T, typename Voxel>
void add_leaves(openvdb::FloatTree& tree, const T* values, const std::array<int64_t, 3>& size, float background,
                const Voxel& voxel)
{
    std::array<int64_t, 3> blocks{};
    for (int d = 0; d < 3; ++d) blocks[d] = (size[d] + kLeafDim - 1) / kLeafDim;
    std::vector<std::unique_ptr<Leaf>> leaves(static_cast<size_t>(blocks[0] * blocks[1] * blocks[2]));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size()), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b != r.end(); ++b) {
            const auto bi = static_cast<int64_t>(b);
            const int64_t x0 = (bi % blocks[0]) * kLeafDim;
            const int64_t y0 = (bi / blocks[0] % blocks[1]) * kLeafDim;
            const int64_t z0 = (bi / (blocks[0] * blocks[1])) * kLeafDim;
            std::unique_ptr<Leaf> leaf;
            for (int64_t z = z0; z < std::min(z0 + kLeafDim, size[2]); ++z)
                for (int64_t y = y0; y < std::min(y0 + kLeafDim, size[1]); ++y) {
                    const T* row = values + (z * size[1] + y) * size[0];
                    for (int64_t x = x0; x < std::min(x0 + kLeafDim, size[0]); ++x) {
                        const std::optional<float> value = voxel(row[x]);
                        if (!value) continue;
                        if (!leaf)
                            leaf = std::make_unique<Leaf>(
                                openvdb::Coord(static_cast<int>(x0), static_cast<int>(y0), static_cast<int>(z0)),
                                background, false);
                        leaf->setValueOn(Leaf::coordToOffset(openvdb::Coord(static_cast<int>(x), static_cast<int>(y),
                                                                            static_cast<int>(z))),
                                         *value);
                    }
                }
            leaves[b] = std::move(leaf);
        }
    });
    for (auto& leaf : leaves)
        if (leaf) tree.addLeaf(leaf.release());
}

std::string labels_text(const std::vector<int>& labels)
{
    std::string out;
    for (int l : labels) out += (out.empty() ? "" : ", ") + std::to_string(l);
    return out;
}

template <typename T>
openvdb::FloatGrid::Ptr to_grid(const T* values, const RawImage& image, const ImageImportParams& params,
                                const std::string& name)
{
    const int64_t count = image.voxels();
    const Stats stats = value_stats(values, count);
    if (stats.nonfinite > 0) {
        const int64_t i = stats.first_nonfinite;
        const int64_t x = i % image.size[0], y = i / image.size[0] % image.size[1],
                      z = i / (image.size[0] * image.size[1]);
        throw InputError(name + " has " + std::to_string(stats.nonfinite) +
                             " NaN or infinite voxel values, the first at voxel (" + std::to_string(x) + ", " +
                             std::to_string(y) + ", " + std::to_string(z) + ")",
                         "fix the image: every voxel needs a finite value");
    }
    const std::string range = "values range from " + number(stats.min) + " to " + number(stats.max);

    openvdb::FloatGrid::Ptr grid;
    if (params.level_set) {
        // Larger than every value in the image, so that outside the image is
        // outside at any iso value within the image's range.
        const double largest = std::max(std::abs(stats.min), std::abs(stats.max));
        const double max_spacing = *std::max_element(image.spacing.begin(), image.spacing.end());
        const double background = largest + max_spacing;
        if (!(background < static_cast<double>(std::numeric_limits<float>::max())))
            throw InputError(name + " has level-set values beyond single precision (" + range + ")",
                             "rescale the level set to physical units");
        if (!(stats.min < 0))
            throw InputError(name + " has no negative voxel, so the level set has no inside (" + range + ")",
                             "a level set must be negative inside; for a label map or an intensity image give a "
                             "label or a threshold instead");
        grid = openvdb::FloatGrid::create(static_cast<float>(background));
        grid->setGridClass(openvdb::GRID_LEVEL_SET);
        grid->setName("level_set");
        add_leaves(grid->tree(), values, image.size, static_cast<float>(background),
                   [](T v) { return std::optional<float>(static_cast<float>(v)); });
        return grid;
    }

    grid = openvdb::FloatGrid::create(0.0f);
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    grid->setName("label");
    const std::optional<float> in(1.0f), out;
    if (params.threshold) {
        const double t = *params.threshold;
        add_leaves(grid->tree(), values, image.size, 0.0f, [&](T v) { return static_cast<double>(v) > t ? in : out; });
        if (grid->activeVoxelCount() == 0)
            throw InputError(name + " has no voxel above the threshold " + number(t) + " (" + range + ")",
                             "choose a threshold between the smallest and largest value");
    } else if (!params.labels.empty()) {
        std::vector<double> labels(params.labels.begin(), params.labels.end());
        add_leaves(grid->tree(), values, image.size, 0.0f, [&](T v) {
            const auto d = static_cast<double>(v);
            return std::find(labels.begin(), labels.end(), d) != labels.end() ? in : out;
        });
        if (grid->activeVoxelCount() == 0)
            throw InputError(std::string(params.labels.size() == 1 ? "label " : "labels ") +
                                 labels_text(params.labels) + " not present in " + name +
                                 "; labels present: " + present_values(values, count),
                             "choose one of the labels present");
    } else {
        add_leaves(grid->tree(), values, image.size, 0.0f, [&](T v) { return v != T(0) ? in : out; });
        if (grid->activeVoxelCount() == 0)
            throw InputError(name + " has no nonzero voxel, so nothing is segmented",
                             "check that this is the segmentation, not an empty mask");
    }
    return grid;
}

openvdb::FloatGrid::Ptr dispatch(const RawImage& image, const ImageImportParams& params, const std::string& name)
{
    const char* data = image.data.get();
    using C = itk::IOComponentEnum;
    // ITK's buffer is aligned for any component type (operator new).
    switch (image.component) {
    case C::UCHAR: return to_grid(reinterpret_cast<const unsigned char*>(data), image, params, name);
    case C::CHAR: return to_grid(reinterpret_cast<const signed char*>(data), image, params, name);
    case C::USHORT: return to_grid(reinterpret_cast<const uint16_t*>(data), image, params, name);
    case C::SHORT: return to_grid(reinterpret_cast<const int16_t*>(data), image, params, name);
    case C::UINT: return to_grid(reinterpret_cast<const uint32_t*>(data), image, params, name);
    case C::INT: return to_grid(reinterpret_cast<const int32_t*>(data), image, params, name);
    case C::ULONG: return to_grid(reinterpret_cast<const unsigned long*>(data), image, params, name);
    case C::LONG: return to_grid(reinterpret_cast<const long*>(data), image, params, name);
    case C::ULONGLONG: return to_grid(reinterpret_cast<const unsigned long long*>(data), image, params, name);
    case C::LONGLONG: return to_grid(reinterpret_cast<const long long*>(data), image, params, name);
    case C::FLOAT: return to_grid(reinterpret_cast<const float*>(data), image, params, name);
    case C::DOUBLE: return to_grid(reinterpret_cast<const double*>(data), image, params, name);
    default: break;
    }
    throw InputError(name + " has voxels of type " + itk::ImageIOBase::GetComponentTypeAsString(image.component) +
                         ", which is not supported",
                     "convert the image to an integer or floating-point type");
}

// Voxels and their frame, from whichever reader, to the grid read_image
// promises.
openvdb::FloatGrid::Ptr voxels_to_grid(const RawImage& image, const ImageImportParams& params, const std::string& name)
{
    const openvdb::math::Transform::Ptr transform = image_transform(image, name);
    openvdb::FloatGrid::Ptr grid = dispatch(image, params, name);
    grid->setTransform(transform);
    grid->insertMeta("image_size", openvdb::Vec3IMetadata(openvdb::Vec3i(static_cast<int>(image.size[0]),
                                                                         static_cast<int>(image.size[1]),
                                                                         static_cast<int>(image.size[2]))));
    return grid;
}

// A .vti's voxels as ITK's would be: the same component types and layout.
RawImage from_vti(VtiVolume volume)
{
    using C = itk::IOComponentEnum;
    using T = vtk_xml::ScalarType;
    RawImage image;
    image.size = volume.size;
    image.spacing = volume.spacing;
    image.origin = volume.origin;
    image.direction = volume.direction;
    switch (volume.type) {
    case T::Int8: image.component = C::CHAR; break;
    case T::UInt8: image.component = C::UCHAR; break;
    case T::Int16: image.component = C::SHORT; break;
    case T::UInt16: image.component = C::USHORT; break;
    case T::Int32: image.component = C::INT; break;
    case T::UInt32: image.component = C::UINT; break;
    case T::Int64: image.component = C::LONGLONG; break;
    case T::UInt64: image.component = C::ULONGLONG; break;
    case T::Float32: image.component = C::FLOAT; break;
    case T::Float64: image.component = C::DOUBLE; break;
    }
    image.data = std::move(volume.data);
    return image;
}

void check_params(const ImageImportParams& params)
{
    const int modes = (params.labels.empty() ? 0 : 1) + (params.threshold ? 1 : 0) + (params.level_set ? 1 : 0);
    if (modes > 1)
        throw InputError("labels, a threshold and a level set were combined",
                         "give at most one of them: labels for a label map, a threshold for an intensity image, "
                         "level set for a signed field");
    if (params.threshold && !std::isfinite(*params.threshold))
        throw InputError("the threshold is not a finite number", "give a finite threshold in the image's units");
}

} // namespace

bool is_image_file(const std::filesystem::path& path) { return format_of(path).has_value(); }

namespace {

// The distinct values of an image, up to ImageValues::kMost of them.
template <typename T> ImageValues values_of(const T* values, int64_t count)
{
    ImageValues out;
    out.integer = std::is_integral_v<T>;
    std::map<double, int64_t> seen;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int64_t i = 0; i < count; ++i) {
        const auto v = static_cast<double>(values[i]);
        if (!std::isfinite(v)) continue;
        lo = std::min(lo, v), hi = std::max(hi, v);
        if (!out.integer && v != std::floor(v)) out.many = true;
        if (out.many) continue;
        ++seen[v];
        if (seen.size() > ImageValues::kMost) out.many = true;
    }
    out.min = lo, out.max = hi;
    if (!out.many) {
        out.counts.assign(seen.begin(), seen.end());
        return out;
    }
    out.histogram.assign(256, 0);
    const double width = hi > lo ? (hi - lo) / 256 : 1;
    for (int64_t i = 0; i < count; ++i) {
        const auto v = static_cast<double>(values[i]);
        if (std::isfinite(v)) ++out.histogram[std::min<int64_t>(255, static_cast<int64_t>((v - lo) / width))];
    }
    return out;
}

RawImage read_raw(const std::filesystem::path& path, int64_t max_bytes)
{
    const std::string name = path.string();
    const std::optional<Format> format = format_of(path);
    if (!format)
        throw InputError(name + " has an unsupported extension '" + path.extension().string() + "'",
                         std::string("medical images are read from ") + kSupported);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) throw IoError(name, "no such file; check the path");
    if (!std::ifstream(path, std::ios::binary))
        throw IoError(name, "cannot be opened for reading; check its permissions");
    if (*format == Format::Vti) return from_vti(read_vti_volume(path));
    if (*format == Format::Nifti) check_nifti(path, max_bytes);
    if (*format == Format::MetaImage) check_metaimage(path);
    return read_with_itk(path, *format, max_bytes);
}

} // namespace

ImageValues image_values(const std::filesystem::path& path, int64_t max_bytes)
{
    const RawImage image = read_raw(path, max_bytes);
    const char* data = image.data.get();
    const int64_t n = image.voxels();
    using C = itk::IOComponentEnum;
    switch (image.component) {
    case C::UCHAR: return values_of(reinterpret_cast<const unsigned char*>(data), n);
    case C::CHAR: return values_of(reinterpret_cast<const signed char*>(data), n);
    case C::USHORT: return values_of(reinterpret_cast<const uint16_t*>(data), n);
    case C::SHORT: return values_of(reinterpret_cast<const int16_t*>(data), n);
    case C::UINT: return values_of(reinterpret_cast<const uint32_t*>(data), n);
    case C::INT: return values_of(reinterpret_cast<const int32_t*>(data), n);
    case C::ULONG: return values_of(reinterpret_cast<const unsigned long*>(data), n);
    case C::LONG: return values_of(reinterpret_cast<const long*>(data), n);
    case C::ULONGLONG: return values_of(reinterpret_cast<const unsigned long long*>(data), n);
    case C::LONGLONG: return values_of(reinterpret_cast<const long long*>(data), n);
    case C::FLOAT: return values_of(reinterpret_cast<const float*>(data), n);
    case C::DOUBLE: return values_of(reinterpret_cast<const double*>(data), n);
    default: break;
    }
    throw InputError(path.string() + " has voxels of type " +
                         itk::ImageIOBase::GetComponentTypeAsString(image.component) + ", which is not supported",
                     "convert the image to an integer or floating-point type");
}

namespace {

// The voxels copied x fastest (the files' layout), in their own type.
template <typename T> void copy_voxels(const VoxelArray& voxels, RawImage& image)
{
    const auto* source = static_cast<const T*>(voxels.data);
    image.data.reset(new char[static_cast<size_t>(image.voxels()) * sizeof(T)]);
    T* target = reinterpret_cast<T*>(image.data.get());
    const std::array<int64_t, 3>& n = image.size;
    const std::array<int64_t, 3>& step = voxels.strides;
    tbb::parallel_for(tbb::blocked_range<int64_t>(0, n[2]), [&](const tbb::blocked_range<int64_t>& r) {
        for (int64_t k = r.begin(); k != r.end(); ++k)
            for (int64_t j = 0; j < n[1]; ++j) {
                const T* row = source + k * step[2] + j * step[1];
                T* out = target + (k * n[1] + j) * n[0];
                for (int64_t i = 0; i < n[0]; ++i) out[i] = row[i * step[0]];
            }
    });
}

} // namespace

openvdb::FloatGrid::Ptr image_grid(const VoxelArray& voxels, const ImageImportParams& params, const std::string& name)
{
    openvdb::initialize();
    check_params(params);
    if (!voxels.data) throw InputError(name + " has no voxels (a null pointer)", "point at voxel (0, 0, 0)");
    RawImage image;
    const std::vector<int64_t> size(voxels.size.begin(), voxels.size.end());
    int64_t count = 1;
    for (int d = 0; d < 3; ++d) {
        if (voxels.size[d] < 1)
            throw InputError(name + " has size " + size_text(size) + "; every axis needs at least one voxel",
                             "give a 3-D volume of voxels");
        if (voxels.size[d] > std::numeric_limits<int>::max() || count * voxels.size[d] > kMaxVoxels)
            throw_too_many_voxels(name, size_text(size));
        count *= voxels.size[d];
        if (!std::isfinite(voxels.spacing[d]) || voxels.spacing[d] <= 0)
            throw InputError(name + " has spacing " + number(voxels.spacing[d]) + " along axis " + std::to_string(d) +
                                 "; spacings must be positive",
                             "give the distance between voxel centres along each axis in mm");
        if (!std::isfinite(voxels.origin[d]))
            throw InputError(name + " has a non-finite origin", "give the centre of voxel (0, 0, 0) in mm");
    }
    image.size = voxels.size;
    image.spacing = voxels.spacing;
    image.origin = voxels.origin;
    for (int d = 0; d < 3; ++d) image.direction[d][d] = 1;
    using C = itk::IOComponentEnum;
    const auto copy = [&]<typename T>(T, C component) {
        require_image_memory(name, static_cast<double>(count), sizeof(T), params.max_bytes);
        image.component = component;
        copy_voxels<T>(voxels, image);
    };
    switch (voxels.type) {
    case VoxelType::UInt8: copy(uint8_t{}, C::UCHAR); break;
    case VoxelType::Int8: copy(int8_t{}, C::CHAR); break;
    case VoxelType::UInt16: copy(uint16_t{}, C::USHORT); break;
    case VoxelType::Int16: copy(int16_t{}, C::SHORT); break;
    case VoxelType::UInt32: copy(uint32_t{}, C::UINT); break;
    case VoxelType::Int32: copy(int32_t{}, C::INT); break;
    case VoxelType::UInt64: copy(static_cast<unsigned long long>(0), C::ULONGLONG); break;
    case VoxelType::Int64: copy(static_cast<long long>(0), C::LONGLONG); break;
    case VoxelType::Float32: copy(float{}, C::FLOAT); break;
    case VoxelType::Float64: copy(double{}, C::DOUBLE); break;
    }
    return voxels_to_grid(image, params, name);
}

openvdb::FloatGrid::Ptr read_image(const std::filesystem::path& path, const ImageImportParams& params)
{
    openvdb::initialize();
    check_params(params);
    return voxels_to_grid(read_raw(path, params.max_bytes), params, path.string());
}

} // namespace scalemesh

