#include "tools/io/json_file.hpp"

#include "common/detail/json_error.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace sinew::tools {

JsonFile read_json_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot open file for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  JsonFile file;
  file.text = buffer.str();
  try {
    file.root = nlohmann::json::parse(file.text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError(common::detail::json_syntax_error(path, file.text, e.what(), e.byte));
  } catch (const nlohmann::json::exception& e) {
    throw InputError(common::detail::json_value_error(path, file.text, e.what()));
  }
  return file;
}

nlohmann::json read_json_file(const std::string& path) {
  return read_json_text(path).root;
}

std::string JsonValueError::located(std::string_view text) const {
  const std::size_t offset = common::detail::JsonLocator(text).find(steps_);
  return file_ + ":" + common::detail::line_column(text, offset) + ": " + message_;
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

JsonCursor::JsonCursor(const JsonCursor& parent, const nlohmann::json& value,
                       common::detail::JsonPathStep step)
    : value_(&value), file_(parent.file_), steps_(parent.steps_) {
  path_ = step.is_key ? (parent.path_.empty() ? step.key : parent.path_ + "." + step.key)
                      : parent.path_ + "[" + std::to_string(step.index) + "]";
  steps_.push_back(std::move(step));
}

JsonCursor JsonCursor::at(const std::string& key) const {
  if (!value_->is_object()) fail("must be an object");
  const auto it = value_->find(key);
  if (it == value_->end()) {
    // Located at the object that lacks it.
    throw JsonValueError(
        file_, steps_,
        "missing required field '" + (path_.empty() ? key : path_ + "." + key) + "'");
  }
  return JsonCursor(*this, *it, {true, key, 0});
}

JsonCursor JsonCursor::at(std::size_t i) const {
  if (!value_->is_array()) fail("must be an array");
  if (i >= value_->size()) fail("has no element " + std::to_string(i));
  return JsonCursor(*this, (*value_)[i], {false, std::string(), i});
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
      // Located at the unknown key's value.
      std::vector<common::detail::JsonPathStep> at = steps_;
      at.push_back({true, item.key(), 0});
      throw JsonValueError(
          file_, std::move(at),
          "unknown key '" + item.key() + "'" + where + " (expected one of: " + list + ")");
    }
  }
}

void JsonCursor::fail(const std::string& what) const {
  throw JsonValueError(file_, steps_, (path_.empty() ? "document" : path_) + " " + what);
}

}  // namespace sinew::tools
