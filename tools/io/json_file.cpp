#include "tools/io/json_file.hpp"

#include "common/detail/json_error.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace sinew::tools {

nlohmann::json read_json_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open file for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(common::detail::json_syntax_error(path, text, e.what(), e.byte));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(common::detail::json_value_error(path, text, e.what()));
  }
}

void write_json_file(const std::string& path, const nlohmann::json& value, int indent) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw InputError(path + ": cannot open file for writing");
    out << value.dump(indent) << "\n";
    out.flush();
    if (!out) throw InputError(path + ": write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw InputError(path + ": cannot move the finished file into place");
  }
}

bool JsonCursor::has(const std::string& key) const {
  return value_->is_object() && value_->contains(key);
}

JsonCursor JsonCursor::at(const std::string& key) const {
  if (!value_->is_object()) fail("must be an object");
  const std::string child = path_.empty() ? key : path_ + "." + key;
  const auto it = value_->find(key);
  if (it == value_->end()) {
    throw InputError(file_ + ": missing required field '" + child + "'");
  }
  return JsonCursor(*it, file_, child);
}

JsonCursor JsonCursor::at(std::size_t i) const {
  if (!value_->is_array()) fail("must be an array");
  if (i >= value_->size()) fail("has no element " + std::to_string(i));
  return JsonCursor((*value_)[i], file_, path_ + "[" + std::to_string(i) + "]");
}

std::size_t JsonCursor::array_size() const {
  if (!value_->is_array()) fail("must be an array");
  return value_->size();
}

double JsonCursor::finite_number() const {
  if (!value_->is_number()) fail("must be a number");
  const double v = value_->get<double>();
  if (!std::isfinite(v)) fail("must be a finite number");
  return v;
}

double JsonCursor::positive_number() const {
  const double v = finite_number();
  if (!(v > 0.0)) {
    std::ostringstream s;
    s << "= " << v << " must be > 0";
    fail(s.str());
  }
  return v;
}

long JsonCursor::integer() const {
  if (!value_->is_number_integer()) fail("must be an integer");
  return value_->get<long>();
}

bool JsonCursor::boolean() const {
  if (!value_->is_boolean()) fail("must be true or false");
  return value_->get<bool>();
}

std::string JsonCursor::string() const {
  if (!value_->is_string()) fail("must be a string");
  return value_->get<std::string>();
}

void JsonCursor::expect_keys(const std::vector<std::string>& allowed) const {
  if (!value_->is_object()) fail("must be an object");
  for (const auto& item : value_->items()) {
    bool known = false;
    for (const auto& a : allowed) known = known || item.key() == a;
    if (!known) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      const std::string where = path_.empty() ? "" : " in " + path_;
      throw InputError(file_ + ": unknown key '" + item.key() + "'" + where +
                       " (expected one of: " + list + ")");
    }
  }
}

void JsonCursor::fail(const std::string& what) const {
  throw InputError(file_ + ": " + (path_.empty() ? "document" : path_) + " " + what);
}

}  // namespace sinew::tools
