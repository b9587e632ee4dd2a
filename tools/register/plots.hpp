#pragma once
/// Pictures of a registration for report readers (seed 003 Figs. 9 and 16): the convergence of the
/// objective and of the marker errors per Gauss–Newton iteration, stage by stage, and the
/// histogram of the final marker errors. PNG, drawn with OpenCV.

#include <string>
#include <vector>

#include "offline/registration/gauss_newton.hpp"

namespace sinew::tools {

/// Histogram of errors (user units, e.g. mm) in 20 bins from 0 to the largest; the mean and the
/// largest marked. False with error when the file cannot be written.
bool write_error_histogram_png(const std::string& path, const std::vector<double>& errors,
                               const std::string& unit, std::string* error = nullptr);

/// Two panels over the iterations (initial fit first): log10 objective, and log10 marker error
/// mean and max (scaled by `scale` into `unit`); stage changes as vertical lines with the stage's
/// name.
bool write_convergence_png(const std::string& path,
                           const std::vector<offline::GaussNewtonIteration>& iterations,
                           double scale, const std::string& unit, std::string* error = nullptr);

}  // namespace sinew::tools
