// Loading station configs: Protocol Buffers text files checked against the
// schema in proto/config_*.proto, then against semantic rules. Every problem
// is reported with its file, line and field; on error the output message is
// left untouched.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace google::protobuf {
class Message;
}

namespace hemm::config {

class RobotConfig;
class OperatorConfig;

struct ConfigError {
  std::string file;
  int line = 0;     // 1-based; 0 when the problem has no single place
  int column = 0;   // 1-based; 0 when unknown
  std::string field;    // dotted path, e.g. "net.session_port"; may be empty
  std::string message;

  // "file:line:column: field: message"
  std::string to_string() const;
};

// A semantic rule broken by a parsed config: the field path and why.
struct FieldIssue {
  std::string field;
  std::string message;
};

// Parses `text` (the contents of `file_name`) into `*out`. Syntax errors,
// unknown fields and type errors are reported with line and column; then
// `issues` (from a validator run on the parsed copy) are mapped back to the
// line where the field was written. `*out` changes only on success.
using Validator = std::vector<FieldIssue> (*)(const google::protobuf::Message&);
std::optional<ConfigError> parse_text_config(const std::string& text, const std::string& file_name,
                                             Validator validate, google::protobuf::Message* out);

// Reads and parses a file. A missing or unreadable file is a ConfigError.
std::optional<ConfigError> load_text_config(const std::string& path, Validator validate,
                                            google::protobuf::Message* out);

std::vector<FieldIssue> validate_robot_config(const google::protobuf::Message& robot_config);
std::vector<FieldIssue> validate_operator_config(const google::protobuf::Message& operator_config);

// Convenience: load + validate each station's config.
std::optional<ConfigError> load_robot_config(const std::string& path, RobotConfig* out);
std::optional<ConfigError> load_operator_config(const std::string& path, OperatorConfig* out);

// A run report (proto/report.proto) as JSON, printed by protobuf: the proto
// field names, every field (zeros too). kIndented: one field a line, ending
// in a newline (files); kOneLine: no whitespace, no newline (log lines).
// This is the tree's one JSON printer. Throws std::runtime_error if protobuf
// cannot print it.
enum class JsonLayout { kIndented, kOneLine };
std::string to_json(const google::protobuf::Message& report, JsonLayout layout = JsonLayout::kIndented);

// Resolves `path` relative to the directory of `config_path` (absolute paths
// are returned unchanged; an empty path stays empty).
std::string resolve_relative_to(const std::string& config_path, const std::string& path);

}  // namespace hemm::config
