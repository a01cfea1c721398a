#pragma once
// Output files are written under a temporary name in the target directory and
// renamed into place only when complete, so no half-written file is ever left
// where a user or the next tool would read it.

#include <filesystem>
#include <string>

namespace scalemesh {

class AtomicOutput {
public:
    // The temporary name keeps the extension of `path`, since some writers
    // (the Gmsh SDK) choose the format from it.
    explicit AtomicOutput(std::filesystem::path path);
    ~AtomicOutput(); // removes the temporary file unless committed
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;

    const std::filesystem::path& temporary() const { return temporary_; }
    const std::filesystem::path& path() const { return path_; }

    // Renames the temporary file onto the final path. Throws IoError.
    void commit();

private:
    std::filesystem::path path_;
    std::filesystem::path temporary_;
    bool committed_ = false;
    int slot_ = -1;
};

// Removes every temporary file still pending; safe to call from a signal
// handler (uses only unlink on pre-built names).
void remove_pending_outputs() noexcept;

} // namespace scalemesh
