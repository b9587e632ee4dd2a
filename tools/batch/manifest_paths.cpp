#include "tools/batch/manifest_paths.hpp"

#include <filesystem>

namespace sinew::tools {

namespace fs = std::filesystem;

std::string resolve_manifest_path(const std::string& manifest_path, const std::string& name) {
  const fs::path p(name);
  if (p.is_absolute()) return p.lexically_normal().string();
  return (fs::path(manifest_path).parent_path() / p).lexically_normal().string();
}

std::string resolve_manifest_path(const std::string& manifest_path, const JsonCursor& field) {
  const std::string name = field.string();
  if (name.empty()) field.fail("must name a file or folder (it is empty)");
  return resolve_manifest_path(manifest_path, name);
}

}  // namespace sinew::tools
