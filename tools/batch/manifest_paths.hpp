#pragma once
/// File and folder names in a batch manifest (sinew-register --batch, sinew-track --batch):
/// relative names are relative to the manifest's folder, so a job may be submitted from anywhere.

#include <string>

#include "tools/io/json_file.hpp"

namespace sinew::tools {

/// The string at `field`, resolved against the folder of `manifest_path` unless absolute, and
/// normalised. Throws (JsonCursor::fail, naming the field) when it is empty or not a string.
std::string resolve_manifest_path(const std::string& manifest_path, const JsonCursor& field);

/// The same for a name that is not a field of the manifest.
std::string resolve_manifest_path(const std::string& manifest_path, const std::string& name);

}  // namespace sinew::tools
