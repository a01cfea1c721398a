#include "gmsh_io/gmsh_session.h"

#include "core/atomic_file.h"
#include "core/errors.h"

#include <gmsh.h>

#include <atomic>
#include <cstdio>
#include <fstream>

#include <fcntl.h>
#include <unistd.h>

namespace scalemesh {

namespace {

std::recursive_mutex& gmsh_mutex()
{
    static std::recursive_mutex mutex;
    return mutex;
}

int g_open_sessions = 0; // guarded by gmsh_mutex()

} // namespace

GmshSession::GmshSession() : lock_(gmsh_mutex())
{
    if (g_open_sessions == 0) {
        // No command-line arguments: the API's argument parser knows only the
        // options of the gmsh program, and an unknown one (such as -noenv) makes
        // it print the usage text and exit the process.
        gmsh::initialize(0, nullptr, /*readConfigFiles=*/false);
        started_ = true;
    }
    ++g_open_sessions;
    try {
        set_option("General.Terminal", 0);
        set_option("General.Verbosity", 0);
    } catch (...) {
        --g_open_sessions;
        if (started_) gmsh::finalize();
        throw;
    }
}

GmshSession::GmshSession(Host) : lock_(gmsh_mutex())
{
    ++g_open_sessions;
}

GmshSession::~GmshSession()
{
    for (auto it = saved_options_.rbegin(); it != saved_options_.rend(); ++it) {
        try {
            gmsh::option::setNumber(it->first, it->second);
        } catch (...) {
            // An option that could be read can be written back; nothing useful
            // can be done in a destructor if Gmsh disagrees.
        }
    }
    --g_open_sessions;
    if (started_) {
        try {
            gmsh::finalize();
        } catch (...) {
            // Finalizing only frees memory; a failure there cannot be reported
            // from a destructor and does not affect any file written.
        }
    }
}

void GmshSession::set_option(const std::string& name, double value)
{
    double previous = 0;
    gmsh::option::getNumber(name, previous);
    saved_options_.emplace_back(name, previous);
    gmsh::option::setNumber(name, value);
}

ScratchModel::ScratchModel(const std::string& prefix)
{
    // Unique names, because gmsh::view::addModelData finds its model by name.
    static std::atomic<int64_t> counter{0};
    name_ = prefix + "_" + std::to_string(++counter);
    gmsh::model::getCurrent(previous_);
    gmsh::model::add(name_);
}

ScratchModel::~ScratchModel()
{
    try {
        for (int view : views_) gmsh::view::remove(view);
        gmsh::model::setCurrent(name_);
        gmsh::model::remove();
        gmsh::model::setCurrent(previous_);
    } catch (...) {
        // Leaving a scratch model behind costs memory only.
    }
}

int ScratchModel::add_view(const std::string& view_name)
{
    const int tag = gmsh::view::add(view_name);
    views_.push_back(tag);
    return tag;
}

void ScratchModel::adopt_views(const std::vector<int>& tags)
{
    views_.insert(views_.end(), tags.begin(), tags.end());
}

namespace {

// Appends the bytes of the file `from` past `offset` to the end of the file
// `to`, by the kernel's copy_file_range (no copy through this process: the
// .msh of a large mesh is gigabytes), or by reads and writes where the file
// system does not offer it.
void append_rest(const std::filesystem::path& from, off_t offset, const std::filesystem::path& to)
{
    const int in = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
    if (in < 0) throw IoError(from.string(), "cannot reopen the written file");
    const int out = ::open(to.c_str(), O_WRONLY | O_CLOEXEC);
    if (out < 0) {
        ::close(in);
        throw IoError(to.string(), "cannot reopen the file");
    }
    off_t in_at = offset;
    off_t out_at = ::lseek(out, 0, SEEK_END);
    bool copied = out_at >= 0;
    while (copied) {
        const ssize_t n = ::copy_file_range(in, &in_at, out, &out_at, size_t{1} << 30, 0);
        if (n == 0) break;
        if (n < 0) copied = false;
    }
    if (!copied) { // EXDEV, ENOSYS, EINVAL: the plain copy from where it stopped
        char buffer[1 << 16];
        bool ok = ::lseek(in, in_at, SEEK_SET) >= 0 && ::lseek(out, 0, SEEK_END) >= 0;
        for (ssize_t n; ok && (n = ::read(in, buffer, sizeof buffer)) != 0;) {
            ok = n > 0;
            for (ssize_t done = 0; ok && done < n;) {
                const ssize_t w = ::write(out, buffer + done, static_cast<size_t>(n - done));
                ok = w > 0;
                done += w;
            }
        }
        if (!ok) {
            ::close(in);
            ::close(out);
            throw IoError(to.string(), "cannot write the file");
        }
    }
    ::close(in);
    if (::close(out) != 0) throw IoError(to.string(), "cannot write the file");
}

} // namespace

void insert_msh_comments(const std::filesystem::path& path, const std::vector<std::string>& lines)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError(path.string(), "cannot reopen the written file");
    AtomicOutput copy(path); // a second temporary name, removed on failure or interruption
    {
        std::ofstream out(copy.temporary(), std::ios::binary);
        if (!out) throw IoError(copy.temporary().string(), "cannot create the file");
        std::string line;
        bool inserted = false;
        while (!inserted && std::getline(in, line)) {
            out << line << '\n';
            if (line.rfind("$EndMeshFormat", 0) == 0) {
                out << "$Comments\n";
                for (const std::string& comment : lines) out << comment << '\n';
                out << "$EndComments\n";
                inserted = true;
            }
        }
        if (!inserted) throw IoError(path.string(), "no $EndMeshFormat line: not a .msh file");
        out.close();
        if (!out) throw IoError(copy.temporary().string(), "cannot write the file");
    }
    const std::streamoff rest = in.tellg(); // the rest, binary or not, unchanged
    in.close();
    if (rest < 0) throw IoError(path.string(), "cannot read the written file");
    append_rest(path, static_cast<off_t>(rest), copy.temporary());
    copy.commit();
}

} // namespace scalemesh
