// Conversion between a parsed sweep file (sweep::SweepSpec) and its wire form
// (totalgrad.v1.SweepSpec), shared by the CLI (which sends what it parsed) and
// the coordinator (which re-validates everything it receives).
#ifndef TOTALGRAD_SERVER_SWEEP_SWEEP_PROTO_H_
#define TOTALGRAD_SERVER_SWEEP_SWEEP_PROTO_H_

#include "totalgrad/v1/types.pb.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::sweep {

// Overwrites every field of *out. No validation: the receiver validates.
void SweepSpecToProto(const SweepSpec& spec, v1::SweepSpec* out);
SweepSpec SweepSpecFromProto(const v1::SweepSpec& spec);

}  // namespace totalgrad::sweep

#endif  // TOTALGRAD_SERVER_SWEEP_SWEEP_PROTO_H_
