#pragma once
/// sinew-track --whiskers --plots DIR: per whisker, the time series a person looks at first (base
/// angle, Δκ, the moment at the follicle, contact), one PNG per whisker, gaps where it was lost.

#include <string>
#include <vector>

namespace sinew::tools {

struct WhiskerSeries {
  int id = 0;
  std::vector<int> frame;
  std::vector<double> base_angle_deg, delta_curvature, moment;  ///< NaN where lost
  std::vector<double> contact;                                  ///< 1 touching, 0 not, NaN unknown
};

/// Writes DIR/whisker_<id>.png for every series (DIR is created). curvature_unit and moment_unit
/// label the axes. False with error on the first file that cannot be written.
bool write_whisker_plots(const std::string& dir, const std::vector<WhiskerSeries>& series,
                         const std::string& curvature_unit, const std::string& moment_unit,
                         std::string* error);

}  // namespace sinew::tools
