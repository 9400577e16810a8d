#include "core/tasks/unicycle.h"

#include <cmath>
#include <numbers>
#include <utility>

#include <Eigen/LU>

#include "core/common/check.h"

namespace totalgrad::tasks {
namespace {

// The constants with short names, and the combinations the equations use.
struct Constants {
  explicit Constants(const UnicycleParams& p)
      : mt(p.turntable_mass), mw(p.wheel_mass), mf(p.frame_mass), rw(p.wheel_radius),
        rf(p.frame_centre_to_wheel), rt(p.frame_centre_to_turntable),
        r(p.frame_centre_to_wheel + p.frame_centre_to_turntable), cw(p.wheel_axial_inertia),
        aw(p.wheel_diametral_inertia), cf(p.frame_inertia_c), bf(p.frame_inertia_b),
        af(p.frame_inertia_a), ct(p.turntable_axial_inertia),
        at(p.turntable_diametral_inertia), g(p.gravity), total_mass(mw + mf + mt),
        first_moment(mf * rf + mt * r), second_moment(mf * rf * rf + mt * r * r),
        pitch_inertia(cw + at + second_moment) {}
  double mt, mw, mf, rw, rf, rt, r, cw, aw, cf, bf, af, ct, at, g;
  double total_mass;     // M
  double first_moment;   // L = mf rf + mt r: frame and turntable about the axle
  double second_moment;  // mf rf^2 + mt r^2
  double pitch_inertia;  // Cw + At + mf rf^2 + mt r^2 (see unicycle.h on Cw)
};

// The configuration's trigonometry and the body rates of unicycle.h.
struct Rates {
  explicit Rates(const Vector& x) {
    dtheta = x(Unicycle::kRollRate);
    dphi = x(Unicycle::kYawRate);
    dpsiw = x(Unicycle::kWheelRate);
    dpsif = x(Unicycle::kPitchRate);
    dpsit = x(Unicycle::kTurntableRate);
    st = std::sin(x(Unicycle::kRoll));
    ct = std::cos(x(Unicycle::kRoll));
    sf = std::sin(x(Unicycle::kPitch));
    cf = std::cos(x(Unicycle::kPitch));
    w1 = dphi * sf * ct + cf * dtheta;
    w2 = -dphi * cf * ct + sf * dtheta;
    w3 = -dphi * st + dpsif;
    wheel_spin = -dphi * st + dpsiw;
    turntable_spin = -w2 + dpsit;
    yaw_roll = dphi * ct * dtheta;
    // The velocity parts of d(w2)/dt and d(w1)/dt.
    dw2 = dphi * sf * dpsif * ct + dphi * cf * st * dtheta + cf * dpsif * dtheta;
    dw1 = dphi * cf * dpsif * ct - dphi * sf * st * dtheta - dpsif * sf * dtheta;
  }
  double dtheta, dphi, dpsiw, dpsif, dpsit;
  double st, ct, sf, cf;
  double w1, w2, w3, wheel_spin, turntable_spin, yaw_roll, dw1, dw2;
};

}  // namespace

Unicycle::Unicycle(const UnicycleParams& params, double dt,
                   const ode::IntegratorOptions& integrator)
    : Plant(dt, integrator), params_(params) {}

void Unicycle::Derivative(const Vector& x, const Vector& u, Vector* dxdt) const {
  TG_CHECK(x.size() == 12 && u.size() == 2);
  const Constants k(params_);
  const Rates q(x);
  const double rw = k.rw, g = k.g;
  const double st = q.st, ct = q.ct, sf = q.sf, cf = q.cf;
  const double w1 = q.w1, w2 = q.w2, w3 = q.w3, ww = q.wheel_spin, wt = q.turntable_spin;
  // Velocity terms of a point mass m at distance l along the frame's axis
  // (the frame's centre, l = rf, or the turntable's, l = r): along the wheel's
  // forward direction (q_along), the axle (r_axle) and the frame's axis
  // (s_axis), with gravity's share (g_along, h_axle).
  auto q_along = [&](double l) {
    return sf * q.dpsif * ww * rw + cf * q.yaw_roll * rw - w3 * sf * ww * rw + q.yaw_roll * l -
           w2 * (q.dtheta * rw + w1 * l);
  };
  auto r_axle = [&](double l) {
    return w1 * sf * ww * rw + q.dw1 * l + w2 * (-cf * ww * rw - w3 * l);
  };
  auto s_axis = [&](double l) {
    return -cf * q.dpsif * ww * rw + sf * q.yaw_roll * rw + w1 * (q.dtheta * rw + w1 * l) -
           w3 * (-cf * ww * rw - w3 * l);
  };
  auto g_along = [&](double l, double m) { return m * (g * sf * ct + q_along(l)); };
  auto h_axle = [&](double l, double m) { return m * (g * st - r_axle(l)); };
  const double f_frame = g_along(k.rf, k.mf), f_turntable = g_along(k.r, k.mt);
  const double k1 = -(k.af + k.ct) * q.dw2 + (k.bf - k.cf) * w1 * w3;
  const double k2 = -(k.bf + k.at) * q.dw1 + (k.cf - k.af + k.at) * w2 * w3 + k.ct * w3 * wt +
                    k.rf * (h_axle(k.rf, k.mf) + h_axle(k.r, k.mt)) + k.rt * h_axle(k.r, k.mt);
  const double gyro = (k.af - k.bf - k.at) * w1 * w2 - k.ct * w1 * wt;
  const double lean = k.rf * (f_frame + f_turntable) + k.rt * f_turntable;
  Eigen::Matrix<double, 5, 1> b;
  b(0) = -u(0) - k.ct * q.dw2;
  b(1) = -u(1) + (k.cw + k.at) * q.yaw_roll + gyro + lean;
  b(2) = -2.0 * k.aw * q.dphi * st * q.dtheta - k.cw * q.dtheta * ww + cf * k1 - sf * k2;
  b(3) = -k.aw * q.dphi * q.dphi * st * ct - k.cw * q.dphi * ct * ww -
         rw * (k.mw * rw * q.dphi * ct * ww - k.total_mass * g * st + k.mf * r_axle(k.rf) +
               k.mt * r_axle(k.r)) +
         sf * k1 + cf * k2;
  b(4) = (2.0 * k.cw + k.at) * q.yaw_roll + gyro + lean +
         rw * (2.0 * k.mw * rw * q.yaw_roll +
               sf * (k.mf * s_axis(k.rf) + k.mt * s_axis(k.r) - (k.mf + k.mt) * g * cf * ct) +
               cf * (f_frame + f_turntable));
  const double lever = rw * k.first_moment;  // rw L
  const double m_rw2 = k.total_mass * rw * rw;
  Eigen::Matrix<double, 5, 5> a = Eigen::Matrix<double, 5, 5>::Zero();
  a.row(0) << -k.ct * sf, k.ct * cf * ct, 0.0, 0.0, k.ct;
  a.row(1) << 0.0, st * (k.pitch_inertia + cf * lever), -cf * lever, -k.pitch_inertia, 0.0;
  a.row(2) << sf * (cf * (k.bf + k.at - k.af - k.ct + k.second_moment) + lever),
      ct * (k.aw + cf * cf * (k.af + k.ct) + sf * sf * (k.bf + k.at + k.second_moment)), 0.0,
      0.0, k.ct * cf;
  a.row(3) << -(k.aw + m_rw2 + 2.0 * cf * lever + sf * sf * (k.af + k.ct) +
                cf * cf * (k.bf + k.at + k.second_moment)),
      sf * ct * (cf * (k.af + k.ct - k.bf - k.at - k.second_moment) - lever), 0.0, 0.0,
      k.ct * sf;
  a.row(4) << 0.0,
      st * (2.0 * k.cw + k.at + k.second_moment + 2.0 * cf * lever + m_rw2),
      -(k.cw + m_rw2 + cf * lever), -(k.pitch_inertia + cf * lever), 0.0;
  const Eigen::Matrix<double, 5, 1> accelerations = -a.partialPivLu().solve(b);
  dxdt->resize(12);
  dxdt->head<5>() = accelerations;
  (*dxdt)(kX) = rw * std::cos(x(kYaw)) * q.dpsiw;
  (*dxdt)(kY) = rw * std::sin(x(kYaw)) * q.dpsiw;
  dxdt->tail<5>() = x.head<5>();
}

double Unicycle::Energy(const Vector& x) const {
  TG_CHECK(x.size() == 12);
  const Constants k(params_);
  const Rates q(x);
  const double rw = k.rw, ww = q.wheel_spin;
  double energy = 0.5 * (k.aw * (q.dtheta * q.dtheta + q.dphi * q.dphi * q.ct * q.ct) +
                         k.cw * ww * ww + k.mw * rw * rw * (ww * ww + q.dtheta * q.dtheta));
  energy += 0.5 * (k.bf * q.w1 * q.w1 + k.af * q.w2 * q.w2 + k.cw * q.w3 * q.w3 +
                   k.at * (q.w1 * q.w1 + q.w3 * q.w3) + k.ct * q.turntable_spin * q.turntable_spin);
  for (const auto& [m, l] : {std::pair{k.mf, k.rf}, std::pair{k.mt, k.r}}) {
    const double forward = rw * ww * q.cf + l * q.w3;
    const double sideways = rw * q.dtheta + l * q.w1;
    const double along_axis = rw * ww * q.sf;
    energy += 0.5 * m * (forward * forward + sideways * sideways + along_axis * along_axis);
  }
  return energy + k.g * q.ct * (k.total_mass * rw + q.cf * k.first_moment);
}

namespace {

// Indices into the cost's state s and its extension y = [s, theta - psif,
// theta + psif].
constexpr int kCostXc = 5, kCostYc = 6, kCostRoll = 7, kCostYaw = 8, kCostPitch = 9;
constexpr int kRollMinusPitch = 10, kRollPlusPitch = 11;

}  // namespace

Vector UnicycleAugmentedEntries(const Vector& ode_state, double wheel_radius) {
  TG_CHECK(ode_state.size() == 12);
  const double phi = ode_state(Unicycle::kYaw), dphi = ode_state(Unicycle::kYawRate);
  const double c = std::cos(phi), s = std::sin(phi);
  const double x = ode_state(Unicycle::kX), y = ode_state(Unicycle::kY);
  const double dx = wheel_radius * c * ode_state(Unicycle::kWheelRate);
  const double dy = wheel_radius * s * ode_state(Unicycle::kWheelRate);
  // (xc, yc) = -[[c, s], [-s, c]] (x, y), and its derivative in time.
  const double xc = -(c * x + s * y), yc = -(-s * x + c * y);
  const double dxc = -(c * dx + s * dy) - dphi * (-s * x + c * y);
  const double dyc = -(-s * dx + c * dy) + dphi * (c * x + s * y);
  Vector out(6);
  out << dx, dy, dxc, dyc, xc, yc;
  return out;
}

Vector UnicycleGpState(const Vector& ode_state, double wheel_radius) {
  const Vector augmented = UnicycleAugmentedEntries(ode_state, wheel_radius);
  Vector out(kUnicycleCostStateDim);
  out << ode_state.head<5>(), augmented(4), augmented(5), ode_state(Unicycle::kRoll),
      ode_state(Unicycle::kYaw), ode_state(Unicycle::kPitch);
  return out;
}

absl::StatusOr<gaussian::GaussianCost> UnicycleCost(const UnicycleCostParams& params) {
  const int d = kUnicycleCostStateDim;
  Matrix map = Matrix::Zero(d + 2, d);  // y = P s
  map.topRows(d).setIdentity();
  map(kRollMinusPitch, kCostRoll) = 1.0;
  map(kRollMinusPitch, kCostPitch) = -1.0;
  map(kRollPlusPitch, kCostRoll) = 1.0;
  map(kRollPlusPitch, kCostPitch) = 1.0;
  // z = [y, (sin, cos) of the angles in increasing y index].
  const std::vector<int> angles = {kCostRoll, kCostPitch, kRollMinusPitch, kRollPlusPitch};
  auto sin_of = [&](int k) { return d + 2 + 2 * k; };  // k: position in `angles`
  auto cos_of = [&](int k) { return d + 3 + 2 * k; };
  const int n = d + 2 + 2 * static_cast<int>(angles.size());
  const double rw = params.wheel_radius, r = params.rod_length;
  Matrix q = Matrix::Zero(n, n);
  Vector target = Vector::Zero(n);
  // Height: rw cos theta + r (cos(theta - psif) + cos(theta + psif)) / 2 against rw + r.
  const int height[3] = {cos_of(0), cos_of(2), cos_of(3)};
  const double height_weights[3] = {rw, r / 2, r / 2};
  for (int i = 0; i < 3; ++i) {
    target(height[i]) = 1.0;
    for (int j = 0; j < 3; ++j) q(height[i], height[j]) += 8.0 * height_weights[i] * height_weights[j];
  }
  target(cos_of(1)) = 1.0;  // cos psif (no weight, as PILCO's target)
  // Forward: xc - r sin psif; sideways: yc - (r + rw) sin theta.
  auto add_pair = [&](int a, int b, double coefficient) {
    q(a, a) += 0.5;
    q(a, b) -= 0.5 * coefficient;
    q(b, a) -= 0.5 * coefficient;
    q(b, b) += 0.5 * coefficient * coefficient;
  };
  add_pair(kCostXc, sin_of(1), r);
  add_pair(kCostYc, sin_of(0), r + rw);
  q(kCostYaw, kCostYaw) = 1.0 / (16.0 * std::numbers::pi * std::numbers::pi);
  absl::StatusOr<gaussian::GaussianCost> of_y =
      gaussian::GaussianCost::Saturating(d + 2, angles, q, target, params.widths);
  if (!of_y.ok()) return of_y.status();
  return gaussian::GaussianCost::OfLinearMap(map, *std::move(of_y));
}

namespace {

// d^2 of loss_unicycle at s and, when grad is non-null, its gradient (10).
double UnicycleDistanceSquared(const UnicycleCostParams& params, const Vector& s, Vector* grad) {
  TG_CHECK(s.size() == kUnicycleCostStateDim);
  const double rw = params.wheel_radius, r = params.rod_length;
  const double ct = std::cos(s(kCostRoll)), st = std::sin(s(kCostRoll));
  const double cp = std::cos(s(kCostPitch)), sp = std::sin(s(kCostPitch));
  const double height = rw * ct + r * ct * cp - rw - r;
  const double forward = s(kCostXc) - r * sp, sideways = s(kCostYc) - (r + rw) * st;
  const double yaw_scale = 1.0 / (4.0 * std::numbers::pi);
  const double yaw = s(kCostYaw) * yaw_scale;
  if (grad != nullptr) {
    grad->setZero(kUnicycleCostStateDim);
    (*grad)(kCostXc) = forward;
    (*grad)(kCostYc) = sideways;
    (*grad)(kCostYaw) = 2.0 * yaw * yaw_scale;
    (*grad)(kCostRoll) = 16.0 * height * (-rw * st - r * st * cp) - sideways * (r + rw) * ct;
    (*grad)(kCostPitch) = 16.0 * height * (-r * ct * sp) - forward * r * cp;
  }
  return 8.0 * height * height + 0.5 * forward * forward + 0.5 * sideways * sideways + yaw * yaw;
}

}  // namespace

double UnicycleCostValue(const UnicycleCostParams& params, const Vector& s) {
  const double d2 = UnicycleDistanceSquared(params, s, nullptr);
  double sum = 0;
  for (double w : params.widths) sum += 1.0 - std::exp(-d2 / (2.0 * w * w));
  return sum / static_cast<double>(params.widths.size());
}

double UnicycleUprightDistance(const UnicycleCostParams& params, const Vector& s) {
  return std::sqrt(UnicycleDistanceSquared(params, s, nullptr));
}

UnicycleStateCost::UnicycleStateCost(const UnicycleCostParams& params) : params_(params) {
  TG_CHECK(!params_.widths.empty());
  for (double w : params_.widths) TG_CHECK(w > 0);
}

void UnicycleStateCost::Evaluate(const ConstRowMatrixRef& x, Vector* cost, RowMatrix* grad) const {
  TG_CHECK(cost != nullptr);
  TG_CHECK_EQ(x.cols(), kUnicycleCostStateDim);
  const Eigen::Index n = x.rows();
  cost->resize(n);
  if (grad != nullptr) grad->resize(n, kUnicycleCostStateDim);
  const double widths = static_cast<double>(params_.widths.size());
  Vector d2_grad;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vector s = x.row(i).transpose();
    const double d2 = UnicycleDistanceSquared(params_, s, grad != nullptr ? &d2_grad : nullptr);
    // c = mean_w (1 - exp(-d2 / (2 w^2))); dc/dd2 = mean_w exp(-d2 / (2 w^2)) / (2 w^2).
    double value = 0, slope = 0;
    for (double w : params_.widths) {
      const double e = std::exp(-d2 / (2.0 * w * w));
      value += 1.0 - e;
      slope += e / (2.0 * w * w);
    }
    (*cost)(i) = value / widths;
    if (grad != nullptr) grad->row(i) = (slope / widths) * d2_grad.transpose();
  }
}

absl::StatusOr<gaussian::GaussianCost> UnicycleStateCost::GaussianExpectation() const {
  return UnicycleCost(params_);
}

}  // namespace totalgrad::tasks
