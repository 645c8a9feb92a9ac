// Number and text formatting of the apps' reports: numbers that read back exactly, JSON and
// CSV values, printf-style cells, aligned text tables, and checked file writes.
#pragma once

#include <cstddef>
#include <filesystem>
#include <ostream>
#include <string>
#include <vector>

namespace vfe::apps {

/// Shortest text that reads back to the same double (6 to 17 significant digits).
std::string round_trip(double v);
/// round_trip, or null for NaN and infinities (JSON has neither).
std::string json_number(double v);
/// round_trip, or nan, inf, -inf (CSV has no null).
std::string csv_number(double v);
/// s as a JSON string literal (quotes, backslashes and control characters escaped).
std::string json_string(const std::string& s);
/// s as one CSV field: quoted (quotes doubled) when it holds a comma, quote or newline.
std::string csv_field(const std::string& s);
/// v printed with a printf format for one double (e.g. "%.3e").
std::string printf_number(const char* format, double v);
/// printf_number, or "-" for NaN (a measure a table has no value for).
std::string table_number(const char* format, double v);

/// Prints rows of cells as aligned columns: rows[0] is the header, underlined with dashes;
/// the first left_columns columns are left-aligned, the others right-aligned.
void print_columns(std::ostream& out, const std::vector<std::vector<std::string>>& rows, std::size_t left_columns);

/// Throws std::runtime_error naming the file when the stream failed.
void check_written(const std::ostream& out, const std::filesystem::path& file);
/// Writes text to file; throws std::runtime_error naming the file when it cannot.
void write_text_file(const std::filesystem::path& file, const std::string& text);

}  // namespace vfe::apps
