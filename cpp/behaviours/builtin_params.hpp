// The built-in behaviours' parameters decoded into their algorithms' structures, for the code that
// reuses the humans' values: the native robot policies (an ORCA robot is configured like ORCA humans)
// and the bindings of the algorithms. A new behaviour needs no entry here unless something else
// reads its parameters.
#pragma once

#include "behaviour.hpp"
#include "orca.hpp"
#include "social_force.hpp"

namespace socialnav {

// The "orca" behaviour's values: the solver's parameters and CrowdSim's radius inflation.
struct OrcaValues {
  OrcaParams solver;
  double radius_margin;  // [m] added to every radius (CrowdSim's 1 cm)
  double safety_space;   // [m] added by the humans on top
};
OrcaValues orca_values(const ParamValues& values);

// The "social_force" behaviour's values (the field of view declared in degrees, held in radians).
SocialForceParams social_force_values(const ParamValues& values);

}  // namespace socialnav
