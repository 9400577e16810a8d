#include "server/sweep/sweep_proto.h"

namespace totalgrad::sweep {

void SweepSpecToProto(const SweepSpec& spec, v1::SweepSpec* out) {
  out->Clear();
  out->set_name(spec.name);
  out->set_description(spec.description);
  for (const auto& axis : spec.grid) {
    auto* a = out->add_grid();
    a->set_key(axis.key);
    for (const auto& v : axis.values) a->add_values(v);
  }
  for (const auto& [key, value] : spec.protocol) {
    auto* o = out->add_protocol();
    o->set_key(key);
    o->set_value(value);
  }
  out->set_max_attempts(spec.max_attempts);
  out->set_max_lost_leases(spec.max_lost_leases);
  out->set_max_concurrent(spec.max_concurrent);
  for (const auto& entry : spec.studies) {
    auto* e = out->add_studies();
    e->set_name(entry.name);
    e->set_spec_json(entry.spec_json);
    e->set_source(entry.source);
  }
}

SweepSpec SweepSpecFromProto(const v1::SweepSpec& spec) {
  SweepSpec out;
  out.name = spec.name();
  out.description = spec.description();
  for (const auto& axis : spec.grid()) {
    out.grid.push_back({axis.key(), {axis.values().begin(), axis.values().end()}});
  }
  for (const auto& option : spec.protocol()) out.protocol.emplace_back(option.key(), option.value());
  out.max_attempts = spec.max_attempts();
  out.max_lost_leases = spec.max_lost_leases();
  out.max_concurrent = spec.max_concurrent();
  for (const auto& entry : spec.studies()) {
    out.studies.push_back({entry.name(), entry.spec_json(), entry.source()});
  }
  return out;
}

}  // namespace totalgrad::sweep
