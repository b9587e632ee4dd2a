#pragma once
/// The fields of one line of the tables sinew-track writes (whiskers.csv: numbers and plain words,
/// comma-separated, nothing quoted); an empty last field after a trailing comma is kept.

#include <string>
#include <vector>

namespace sinew::tools {

std::vector<std::string> split_csv_fields(const std::string& line);

}  // namespace sinew::tools
