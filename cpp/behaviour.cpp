#include "behaviour.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace socialnav {

namespace {

// Function-local statics: filled by the registrars whatever the order the files' statics run in.
std::vector<std::unique_ptr<BehaviourInfo>>& registry() {  // stable addresses: callers keep pointers
  static std::vector<std::unique_ptr<BehaviourInfo>> entries;
  return entries;
}

std::string& duplicate() {  // the first name registered twice, "" if none
  static std::string name;
  return name;
}

// x as %g writes it (6 significant digits), as an ostringstream did. snprintf rather than an ostringstream:
// iostreams reach libstdc++'s global locale, which a core linked with its own copy of libstdc++ (a toolchain
// that links it statically) may share with the copy a Python process already loaded, and then crash in; C's
// snprintf is in every C library (std::to_chars for doubles needs GCC 11).
std::string number(double x) {
  char text[32];
  const int n = std::snprintf(text, sizeof text, "%g", x);
  return std::string(text, n > 0 ? static_cast<size_t>(n) : 0);
}

}  // namespace

ParamValues::ParamValues(const std::string& behaviour, const std::vector<BehaviourParam>& params,
                         const std::vector<double>& values)
    : params_(&params), behaviour_(behaviour) {
  if (values.empty()) {
    for (const BehaviourParam& p : params) values_.push_back(p.default_value);
    return;
  }
  if (values.size() != params.size())
    throw std::invalid_argument(behaviour + ": expected " + std::to_string(params.size()) + " parameter values, got " +
                                std::to_string(values.size()));
  for (size_t k = 0; k < params.size(); ++k) {
    const BehaviourParam& p = params[k];
    const double v = values[k];
    // The message is written only for a value that fails a check.
    auto refuse = [&](const std::string& rule) {
      throw std::invalid_argument(behaviour + "." + p.name + " must be " + rule + ", got " + number(v));
    };
    if (!std::isfinite(v)) refuse("finite");
    if (p.integer && std::floor(v) != v) refuse("an integer");
    if (!std::isnan(p.gt) && !(v > p.gt)) refuse("> " + number(p.gt));
    if (!std::isnan(p.ge) && !(v >= p.ge)) refuse(">= " + number(p.ge));
    if (!std::isnan(p.lt) && !(v < p.lt)) refuse("< " + number(p.lt));
    if (!std::isnan(p.le) && !(v <= p.le)) refuse("<= " + number(p.le));
  }
  values_ = values;
}

void HumanBehaviour::preferred_velocities(const SlotView& s, const double* targets, Vec2* out) const {
  for (int i = 1; i < s.agents; ++i)
    if (s.mask[i]) out[i] = preferred_velocity(s.at(s.position, i), s.at(targets, i), s.v_pref[i], s.dt);
}

double ParamValues::get(const std::string& name) const {
  for (size_t k = 0; k < params_->size(); ++k)
    if ((*params_)[k].name == name) return values_[k];
  throw std::logic_error(behaviour_ + " declares no parameter '" + name + "'");
}

std::vector<const BehaviourInfo*> human_behaviours() {
  if (!duplicate().empty()) throw std::logic_error("two pedestrian behaviours are registered as '" + duplicate() + "'");
  std::vector<const BehaviourInfo*> out;
  for (const auto& info : registry()) out.push_back(info.get());
  std::sort(out.begin(), out.end(), [](const BehaviourInfo* a, const BehaviourInfo* b) {
    return a->order != b->order ? a->order < b->order : a->name < b->name;
  });
  return out;
}

const BehaviourInfo& human_behaviour(const std::string& name) {
  std::string names;
  for (const BehaviourInfo* info : human_behaviours()) {
    if (info->name == name) return *info;
    names += (names.empty() ? "" : ", ") + info->name;
  }
  throw std::invalid_argument("unknown pedestrian behaviour '" + name + "'; registered: " + names);
}

std::unique_ptr<HumanBehaviour> make_human_behaviour(const std::string& name, const std::vector<double>& values,
                                                     int threads, int agents) {
  const BehaviourInfo& info = human_behaviour(name);
  const ParamValues params(info.name, info.params, values);
  return info.make(BehaviourSetup{params, std::max(1, threads), agents});
}

BehaviourRegistrar::BehaviourRegistrar(BehaviourInfo info) {
  for (const auto& other : registry())
    if (other->name == info.name && duplicate().empty()) duplicate() = info.name;
  registry().push_back(std::make_unique<BehaviourInfo>(std::move(info)));
}

}  // namespace socialnav
