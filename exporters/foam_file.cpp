#include "exporters/foam_file.h"

#include "core/errors.h"

#include <memory>

namespace scalemesh {

std::string foam_file_header(bool binary, const std::string& cls, const std::string& location,
                             const std::string& object, const std::string& note)
{
    std::string text = "FoamFile\n{\n    version     2.0;\n    format      ";
    text += binary ? "binary" : "ascii";
    text += ";\n    arch        \"LSB;label=32;scalar=64\";\n    class       " + cls + ";\n    location    \"" +
            location + "\";\n";
    if (!note.empty()) text += "    note        \"" + note + "\";\n";
    return text + "    object      " + object + ";\n}\n\n";
}

FoamFileOutput::FoamFileOutput(const std::filesystem::path& path, StagedOutputs& outputs) : path_(path)
{
    outputs.push_back(std::make_unique<AtomicOutput>(path, true));
    out_.open(outputs.back()->temporary(), std::ios::binary);
    if (!out_) throw IoError(path.string(), "cannot open for writing");
}

void FoamFileOutput::finish()
{
    text("\n// ************************************************************************* //\n");
    out_.flush();
    if (!out_) throw IoError(path_.string(), "cannot write the file (disk full?)");
}

void write_foam_file(const std::filesystem::path& path, std::string_view text, StagedOutputs& outputs)
{
    FoamFileOutput file(path, outputs);
    file.text(text);
    file.finish();
}

} // namespace scalemesh
