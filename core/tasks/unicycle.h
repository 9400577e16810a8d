// The robotic unicycle of PILCO's unicycle scene (scenarios/unicycle at
// a0b48b7, dynamics_unicycle.m, after Forster's derivation): a wheel rolling
// without slipping on the ground, a frame (fork) pivoting on the wheel's
// axle, and a turntable (flywheel) on top of the frame, spinning about the
// frame's axis. Two torques: u = [V, U], V on the turntable and U on the
// wheel, each acting between that body and the frame. No friction.
//
// State x (12, PILCO's ODE state, odei order):
//   [dtheta, dphi, dpsiw, dpsif, dpsit, x, y, theta, phi, psiw, psif, psit]
//   theta roll (tilt sideways), phi yaw (heading), psiw the wheel's angle,
//   psif the frame's pitch, psit the turntable's angle; (x, y) the contact
//   point on the ground. Upright is theta = psif = 0. Angles never wrapped.
//
// Equations (the published ones, regrouped; unicycle.cc names the terms).
// With st = sin theta, ct = cos theta, sf = sin psif, cf = cos psif, the
// angular velocities of the frame in its own axes (forward f', axle a,
// frame axis n')
//   w1 = dphi sf ct + cf dtheta,  w3 = dpsif - dphi st,  -w2 = dphi cf ct - sf dtheta,
// the wheel's spin ww = dpsiw - dphi st and the turntable's wt = dpsit - w2,
// the five accelerations solve A(q) [ddtheta ddphi ddpsiw ddpsif ddpsit]' = -b
// (5 x 5, dense LU), and dx = rw cos(phi) dpsiw, dy = rw sin(phi) dpsiw.
//
// Energy (conserved without torques; with them dE/dt = V dpsit + U (dpsiw -
// dpsif), the power of the two torques; both tested):
//   E = [Aw (dtheta^2 + dphi^2 ct^2) + Cw ww^2 + mw rw^2 (ww^2 + dtheta^2)] / 2
//     + [Bf w1^2 + Af w2^2 + Cw w3^2 + At (w1^2 + w3^2) + Ct wt^2] / 2
//     + sum over (m, l) in {(mf, rf), (mt, rf + rt)} of
//         m [(rw ww cf + l w3)^2 + (rw dtheta + l w1)^2 + (rw ww sf)^2] / 2
//     + g ct (M rw + cf (mf rf + mt (rf + rt))),   M = mw + mf + mt.
// The frame's inertia about its pitch axis enters the published equations as
// Cw (the wheel's axial inertia), not Cf: the energy above, with Cw there, is
// what they conserve (with Cf it drifts by percents within a second), and
// Cf appears only in gyroscopic terms. We keep the equations as published.
//
// Thread safety: immutable after construction.
#ifndef TOTALGRAD_CORE_TASKS_UNICYCLE_H_
#define TOTALGRAD_CORE_TASKS_UNICYCLE_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/gaussian/expected_cost.h"
#include "core/tasks/cost.h"
#include "core/tasks/plant.h"

namespace totalgrad::tasks {

// The constants at the top of dynamics_unicycle.m (SI units).
struct UnicycleParams {
  double turntable_mass = 10.0;            // mt
  double wheel_mass = 1.0;                 // mw
  double frame_mass = 23.5;                // mf
  double wheel_radius = 0.225;             // rw
  double frame_centre_to_wheel = 0.54;     // rf: the frame's centre of mass above the axle
  double frame_centre_to_turntable = 0.27; // rt
  double wheel_axial_inertia = 0.0484;     // Cw
  double wheel_diametral_inertia = 0.0242; // Aw
  double frame_inertia_c = 0.8292;         // Cf (in gyroscopic terms only; see above)
  double frame_inertia_b = 0.4608;         // Bf (about the forward axis)
  double frame_inertia_a = 0.4248;         // Af (about the frame's axis)
  double turntable_axial_inertia = 0.2;    // Ct
  double turntable_diametral_inertia = 1.3;  // At
  double gravity = 9.82;
};

class Unicycle final : public Plant {
 public:
  // Indices into the state (PILCO's ODE order).
  enum Index {
    kRollRate, kYawRate, kWheelRate, kPitchRate, kTurntableRate,
    kX, kY, kRoll, kYaw, kWheel, kPitch, kTurntable,
  };

  Unicycle(const UnicycleParams& params, double dt, const ode::IntegratorOptions& integrator);
  int state_dim() const override { return 12; }
  int control_dim() const override { return 2; }
  // u = [V (turntable), U (wheel)] in N m.
  void Derivative(const Vector& x, const Vector& u, Vector* dxdt) const override;
  double Energy(const Vector& x) const override;
  const UnicycleParams& params() const { return params_; }

 private:
  UnicycleParams params_;
};

// PILCO's augmented entries of a state (augment_unicycle.m), computed from
// the 12 ODE values after each step: [dx, dy, dxc, dyc, xc, yc], the
// contact point's velocity on the ground, and the origin (the goal) in the
// unicycle's coordinates, (xc, yc) = -R(phi)^T (x, y), with its time
// derivative (dxc, dyc). The wheel radius is the plant's.
Vector UnicycleAugmentedEntries(const Vector& ode_state, double wheel_radius);
// The state the GP predicts and the cost reads (PILCO's dyno order):
// [dtheta, dphi, dpsiw, dpsif, dpsit, xc, yc, theta, phi, psif].
Vector UnicycleGpState(const Vector& ode_state, double wheel_radius);

// PILCO's loss_unicycle (scenarios/unicycle, cost.p = [rw, r] = [0.22,
// 0.81], width 1) on the unicycle's GP state (PILCO's dyno order)
//   s = [dtheta, dphi, dpsiw, dpsif, dpsit, xc, yc, theta, phi, psif]
// (xc, yc: the contact point in the unicycle's coordinates): for each width
// w, 1 - exp(-d^2 / (2 w^2)), the mean over the widths, with
//   d^2 = 8 (rw cos theta + r cos theta cos psif - rw - r)^2   (the top's height)
//       + (xc - r sin psif)^2 / 2 + (yc - (r + rw) sin theta)^2 / 2
//       + (phi / (4 pi))^2,
// the distance of the configuration to upright over the origin facing 0.
// PILCO writes it as lossSat on z = [s, theta - psif, theta + psif, and
// (sin, cos) of theta, psif, theta - psif, theta + psif], so that
// cos theta cos psif = (cos(theta - psif) + cos(theta + psif)) / 2 is linear
// in z; UnicycleCost builds that (the Gaussian of z as gTrig's, exact in
// its first two moments) as gaussian::GaussianCost::OfLinearMap.
struct UnicycleCostParams {
  double wheel_radius = 0.22;  // rw of the cost (the plant's is 0.225)
  double rod_length = 0.81;    // r
  std::vector<double> widths = {1.0};
};
inline constexpr int kUnicycleCostStateDim = 10;
absl::StatusOr<gaussian::GaussianCost> UnicycleCost(const UnicycleCostParams& params = {});
// The cost of one state s (10 entries as above): d^2 written out, not
// through z.
double UnicycleCostValue(const UnicycleCostParams& params, const Vector& s);
// d of the loss above (sqrt of d^2): how far the configuration s is from
// upright over the origin facing 0, the unicycle's goal distance.
double UnicycleUprightDistance(const UnicycleCostParams& params, const Vector& s);

// loss_unicycle as the per-step cost of a trial on the unicycle, on the GP
// state s (10 entries, PILCO's dyno order): the value UnicycleCostValue's,
// the gradient of d^2 written out (FD-tested), the Gaussian form
// UnicycleCost's. Widths must be > 0 (CHECK).
class UnicycleStateCost final : public StateCost {
 public:
  explicit UnicycleStateCost(const UnicycleCostParams& params = {});
  void Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const override;
  std::string Name() const override { return "unicycle"; }
  absl::StatusOr<gaussian::GaussianCost> GaussianExpectation() const override;

 private:
  UnicycleCostParams params_;
};

}  // namespace totalgrad::tasks

#endif  // TOTALGRAD_CORE_TASKS_UNICYCLE_H_
