// Tables of the comparison: one row per reconstruction, one per pair of reconstructions, as
// Markdown (readable in the test log and in docs/comparisons.md).
#pragma once

#include "mesh_metrics.hpp"

#include <cstdarg>
#include <cstdio>
#include <string>
#include <vector>

namespace report {

inline std::string format(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
inline std::string format(const char *fmt, ...) {
    char buf[512];
    va_list args;
    va_start(args, fmt);
    std::vsnprintf(buf, sizeof buf, fmt, args);
    va_end(args);
    return buf;
}

// A Markdown table built row by row.
class Table {
public:
    explicit Table(std::vector<std::string> header) : header_(std::move(header)) {}
    void row(std::vector<std::string> cells) { rows_.push_back(std::move(cells)); }
    std::string str() const {
        std::string out = line(header_);
        out += "|";
        for (std::size_t i = 0; i < header_.size(); ++i) out += i == 0 ? "---|" : "---:|";
        out += "\n";
        for (const auto &r : rows_) out += line(r);
        return out;
    }

private:
    static std::string line(const std::vector<std::string> &cells) {
        std::string out = "|";
        for (const auto &c : cells) out += " " + c + " |";
        return out + "\n";
    }
    std::vector<std::string> header_;
    std::vector<std::vector<std::string>> rows_;
};

// Distances are fractions of the bounding-box diagonal; shown in units of 1e-3 (per mille).
inline std::string permille(double x) { return format("%.3f", 1e3 * x); }

} // namespace report
