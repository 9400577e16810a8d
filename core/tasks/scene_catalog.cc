#include "core/tasks/scene_catalog.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "core/common/check.h"
#include "core/common/closest_word.h"

namespace totalgrad::tasks {
namespace {

constexpr double kPi = std::numbers::pi;

Vector Values(std::initializer_list<double> values) {
  Vector v(static_cast<Eigen::Index>(values.size()));
  Eigen::Index i = 0;
  for (double x : values) v(i++) = x;
  return v;
}

// Q = C^T C placed on the z indices `at` of a z of dimension n.
Matrix QuadraticOn(int n, const std::vector<int>& at, const Matrix& c) {
  const Matrix block = c.transpose() * c;
  Matrix q = Matrix::Zero(n, n);
  for (size_t i = 0; i < at.size(); ++i)
    for (size_t j = 0; j < at.size(); ++j) q(at[i], at[j]) = block(i, j);
  return q;
}

SceneDefinition PendulumScene() {
  SceneDefinition s;
  s.name = "pendulum";
  s.summary = "pendulum swing-up (PILCO's pendulum): a rod on a pivot, one torque";
  s.plant = PlantKind::kPendulum;
  s.pendulum = PendulumParams{1.0, 1.0, 0.01, 9.82};
  s.dt = 0.1;
  s.state_names = {"dtheta", "theta"};
  s.state_units = {"rad/s", "rad"};
  s.control_names = {"torque"};
  s.max_control = Values({2.5});
  s.horizon = 40;
  s.success_threshold = 0.5 * s.horizon;
  s.mu0 = Values({0.0, 0.0});
  s.start_std = Values({0.1, 0.1});
  s.measurement_noise_std = Values({0.1, 0.01});
  s.target = Values({0.0, kPi});
  s.angle_indices = {1};
  s.dynamics_inputs = {0, 2, 3};
  s.policy_inputs = {0, 2, 3};
  // Q = l^2 on the (sin, cos) block (l = 1), width 0.5.
  s.saturating_cost.q = QuadraticOn(4, {2, 3}, Matrix::Identity(2, 2));
  s.saturating_cost.widths = {0.5};
  s.angle_cost_q = Values({0.0, 1.0});
  s.basis_functions = 20;
  s.inducing_inputs = 300;
  s.learned_episodes = 10;
  s.line_searches = 75;
  s.evaluations_per_line_search = 30;
  s.source = "PILCO a0b48b7 scenarios/pendulum (settings_pendulum.m, dynamics_pendulum.m, "
             "loss_pendulum.m)";
  return s;
}

SceneDefinition CartPoleScene(bool balance) {
  SceneDefinition s;
  s.name = balance ? "cartpole-balance" : "cartpole-swingup";
  s.summary = balance ? "cart-pole balancing from upright (the paper's cart-pole)"
                      : "cart-pole swing-up (the paper's cart-pole; PILCO's constants)";
  s.plant = PlantKind::kCartPole;
  s.cartpole = CartPoleParams{};
  s.dt = 0.1;
  s.state_names = {"s", "beta", "s_dot", "beta_dot"};
  s.state_units = {"m", "rad", "m/s", "rad/s"};
  s.control_names = {"force"};
  s.max_control = Values({10.0});
  s.horizon = 30;
  s.success_threshold = 15.0;  // the paper's
  s.target = Values({0.0, kPi, 0.0, 0.0});
  s.mu0 = balance ? s.target : Values({0.0, 0.0, 0.0, 0.0});
  s.start_std = Values({0.1, 0.1, 0.1, 0.1});
  // The paper's base noise (0.01 m, 1 deg, 0.1 m/s, 10 deg/s), x sqrt(noise_k).
  s.measurement_noise_std = Values({0.01, kPi / 180.0, 0.1, 10.0 * kPi / 180.0});
  s.angle_indices = {1};
  // z = [s, beta, s_dot, beta_dot, sin beta, cos beta]; PILCO's dyni = poli
  // = [1 2 3 5 6] in its order [x, v, dtheta, theta] is every dimension but
  // the raw angle.
  s.dynamics_inputs = {0, 2, 3, 4, 5};
  s.policy_inputs = {0, 2, 3, 4, 5};
  // PILCO's tip cost (loss_cp): d^2 = (s + l sin beta)^2 + (l cos beta + l)^2
  // in our angle convention, width 0.25, l = 0.5: Q = C^T C with
  // C = [[1, l, 0], [0, 0, l]] on [s, sin beta, cos beta] and z_t = target.
  Matrix c(2, 3);
  c << 1.0, 0.5, 0.0, 0.0, 0.0, 0.5;
  s.saturating_cost.q = QuadraticOn(6, {0, 4, 5}, c);
  s.saturating_cost.widths = {0.25};
  s.angle_cost_q = Values({1.0, 1.0, 0.0, 0.0});
  s.basis_functions = 50;
  s.inducing_inputs = 300;
  s.learned_episodes = 15;
  s.line_searches = 150;
  s.evaluations_per_line_search = 30;
  s.source = "the paper's cart-pole (docs/core.md, docs/scenes.md); PILCO a0b48b7 "
             "scenarios/cartPole for the constants, index sets and tip cost";
  return s;
}

SceneDefinition CartDoublePendulumScene() {
  SceneDefinition s;
  s.name = "cart-double-pendulum";
  s.summary = "cart with a double pendulum, swing-up of both links, one force";
  s.plant = PlantKind::kCartDoublePendulum;
  s.cart_double_pendulum = CartDoublePendulumParams{0.5, 0.5, 0.5, 0.6, 0.6, 0.1, 9.82};
  s.dt = 0.05;
  s.state_names = {"x", "dx", "dtheta1", "dtheta2", "theta1", "theta2"};
  s.state_units = {"m", "m/s", "rad/s", "rad/s", "rad", "rad"};
  s.control_names = {"force"};
  s.max_control = Values({20.0});
  s.horizon = 100;
  s.success_threshold = 0.5 * s.horizon;
  s.mu0 = Values({0, 0, 0, 0, kPi, kPi});
  s.start_std = Values({0.1, 0.1, 0.1, 0.1, 0.01, 0.01});
  s.measurement_noise_std = Vector::Constant(6, 0.01);
  s.target = Vector::Zero(6);
  s.angle_indices = {4, 5};
  s.dynamics_inputs = {0, 1, 2, 3, 6, 7, 8, 9};
  s.policy_inputs = {0, 1, 2, 3, 6, 7, 8, 9};
  // Q = C^T C on [x, sin th1, cos th1, sin th2, cos th2], C = [[1, -l1, 0,
  // -l2, 0], [0, 0, l1, 0, l2]] with l1 = l2 = 1 (PILCO's cost.p, not the
  // links' 0.6), width 0.5.
  Matrix c(2, 5);
  c << 1.0, -1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0;
  s.saturating_cost.q = QuadraticOn(10, {0, 6, 7, 8, 9}, c);
  s.saturating_cost.widths = {0.5};
  s.angle_cost_q = Values({1.0, 0.0, 0.0, 0.0, 1.0, 1.0});
  s.basis_functions = 200;
  s.inducing_inputs = 400;
  s.learned_episodes = 40;
  s.line_searches = 150;
  s.evaluations_per_line_search = 30;
  s.source = "PILCO a0b48b7 scenarios/cartDoublePendulum (settings_cdp.m, dynamics_cdp.m, "
             "loss_cdp.m)";
  return s;
}

SceneDefinition DoublePendulumScene(bool pendubot) {
  SceneDefinition s;
  s.name = pendubot ? "pendubot" : "double-pendulum";
  s.summary = pendubot ? "pendubot swing-up: a double pendulum with a torque at the first joint only"
                       : "double pendulum swing-up with a torque at each joint";
  s.plant = PlantKind::kDoublePendulum;
  s.double_pendulum.mass1 = s.double_pendulum.mass2 = 0.5;
  s.double_pendulum.length1 = s.double_pendulum.length2 = 0.5;
  s.double_pendulum.gravity = 9.82;
  s.double_pendulum.input_map = pendubot ? Matrix(Values({1.0, 0.0})) : Matrix(Matrix::Identity(2, 2));
  s.dt = pendubot ? 0.05 : 0.1;
  s.state_names = {"dtheta1", "dtheta2", "theta1", "theta2"};
  s.state_units = {"rad/s", "rad/s", "rad", "rad"};
  s.control_names = pendubot ? std::vector<std::string>{"torque1"}
                             : std::vector<std::string>{"torque1", "torque2"};
  s.max_control = pendubot ? Values({3.5}) : Values({2.0, 2.0});
  s.horizon = pendubot ? 60 : 30;
  s.success_threshold = 0.5 * s.horizon;
  s.mu0 = Values({0, 0, kPi, kPi});
  s.start_std = Values({0.1, 0.1, 0.01, 0.01});
  s.measurement_noise_std = Vector::Constant(4, 0.01);
  s.target = Vector::Zero(4);
  s.angle_indices = {2, 3};
  s.dynamics_inputs = {0, 1, 4, 5, 6, 7};
  s.policy_inputs = {0, 1, 4, 5, 6, 7};
  // Q = C^T C on [sin th1, cos th1, sin th2, cos th2], C = [[l1, 0, l2, 0],
  // [0, l1, 0, l2]], l = 0.5; width 0.5 (pendubot 0.25).
  Matrix c(2, 4);
  c << 0.5, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0, 0.5;
  s.saturating_cost.q = QuadraticOn(8, {4, 5, 6, 7}, c);
  s.saturating_cost.widths = {pendubot ? 0.25 : 0.5};
  s.angle_cost_q = Values({0.0, 0.0, 1.0, 1.0});
  s.basis_functions = pendubot ? 200 : 100;
  s.inducing_inputs = 300;
  s.learned_episodes = pendubot ? 40 : 20;
  s.line_searches = 150;
  s.evaluations_per_line_search = pendubot ? 20 : 30;
  s.source = pendubot ? "PILCO a0b48b7 scenarios/pendubot (settings_pendubot.m, dynamics_pendubot.m, "
                        "loss_pendubot.m)"
                      : "PILCO a0b48b7 scenarios/doublePendulum (settings_dp.m, dynamics_dp.m, "
                        "loss_dp.m)";
  return s;
}

// PILCO's robotic unicycle (scenarios/unicycle: settings_unicycle.m,
// dynamics_unicycle.m, loss_unicycle.m, augment_unicycle.m). The state here
// is the plant's: the 12 values PILCO's ODE integrates (odei). PILCO's full
// state adds 6 augmented entries and 2 torques (20); its GP predicts 10 of
// them (dyno) from 9 (dyni), its linear policy reads 10 (poli): the
// learner sees those 10 (learner_mu0 below), the plant's 12 are mapped to
// them after each step.
SceneDefinition UnicycleScene() {
  SceneDefinition s;
  s.name = "unicycle";
  s.summary = "PILCO's robotic unicycle: balance upright with a turntable and a wheel torque";
  s.plant = PlantKind::kUnicycle;
  s.dt = 0.15;
  s.state_names = {"dtheta", "dphi", "dpsiw", "dpsif", "dpsit", "x",
                   "y",      "theta", "phi",  "psiw",  "psif",  "psit"};
  s.state_units = {"rad/s", "rad/s", "rad/s", "rad/s", "rad/s", "m",
                   "m",     "rad",   "rad",   "rad",   "rad",   "rad"};
  s.control_names = {"turntable", "wheel"};
  s.max_control = Values({10.0, 50.0});
  s.horizon = 67;  // 10 s
  s.success_threshold = 0.5 * s.horizon;
  s.mu0 = Vector::Zero(12);
  s.start_std = Values({0.02, 0.02, 0.02, 0.02, 0.02, 0.1, 0.1, 0.02, 0.02, 0.02, 0.02, 0.02});
  s.measurement_noise_std = Values({0.01, 0.01, 0.01, 0.01, 0.01, 0.003, 0.003, 0.003, 0.003,
                                    0.003, 0.003, 0.003});
  s.target = Vector::Zero(12);
  // PILCO's full state of 20: [dx dy dxc dyc | dtheta dphi dpsiw dpsif
  // dpsit | x y | xc yc | theta phi psiw psif psit | V U] and its sets
  // (settings_unicycle.m: odei, augi, dyno, dyni, poli; minus one).
  s.full_state.names = {"dx",    "dy",    "dxc", "dyc", "dtheta", "dphi", "dpsiw",
                        "dpsif", "dpsit", "x",   "y",   "xc",     "yc",   "theta",
                        "phi",   "psiw",  "psif", "psit", "V",     "U"};
  s.full_state.integrated = {4, 5, 6, 7, 8, 9, 10, 13, 14, 15, 16, 17};
  s.full_state.augmented = {0, 1, 2, 3, 11, 12};
  s.full_state.controls = {18, 19};
  s.full_state.predicted = {4, 5, 6, 7, 8, 11, 12, 13, 14, 16};
  s.full_state.dynamics_inputs = {0, 1, 2, 3, 4, 5, 6, 7, 9};
  s.full_state.policy_inputs = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  s.cost_kind = "unicycle";
  s.default_cost = "unicycle";
  s.policy_class = "linear";
  // The learner's state is PILCO's dyno (UnicycleGpState): the GP predicts
  // all 10 as differences from 9 (dyni: all but the yaw, to which the
  // dynamics are blind), the policy reads all 10 (poli). Its start: PILCO
  // projects mu0 and S0 onto dyno with the augmented (xc, yc) at variance
  // 0; here (xc, yc) = -R(phi)^T (x, y) take the spread of (x, y), std 0.1
  // (exact to first order in the yaw's 0.02), which is what the real
  // episodes start from.
  s.learner_mu0 = Vector::Zero(kUnicycleCostStateDim);
  s.learner_state_names = {"dtheta", "dphi", "dpsiw", "dpsif", "dpsit",
                           "xc",     "yc",   "theta", "phi",   "psif"};
  s.learner_start_std = Values({0.02, 0.02, 0.02, 0.02, 0.02, 0.1, 0.1, 0.02, 0.02, 0.02});
  s.dynamics_inputs = {0, 1, 2, 3, 4, 5, 6, 7, 9};
  s.policy_inputs = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
  s.random_episodes = 10;
  s.random_control_fraction = 0.2;
  // plant.constraint: |theta| or |psif| > pi/2 (in the ODE state).
  s.episode_end_indices = {Unicycle::kRoll, Unicycle::kPitch};
  s.episode_end_bound = std::numbers::pi / 2;
  s.studies_unavailable =
      "a study's problems (synthetic, or frozen from a trial's snapshot) take the RBF policy on "
      "the plant's own state; the unicycle's learner state and linear policy are not in them";
  s.basis_functions = 0;  // a linear policy
  s.inducing_inputs = 300;
  s.learned_episodes = 40;
  s.line_searches = 150;
  s.evaluations_per_line_search = 20;
  s.source = "PILCO a0b48b7 scenarios/unicycle (settings_unicycle.m, dynamics_unicycle.m, "
             "loss_unicycle.m, augment_unicycle.m)";
  return s;
}

}  // namespace

const std::vector<SceneDefinition>& SceneCatalog() {
  static const std::vector<SceneDefinition>* catalog = new std::vector<SceneDefinition>{
      PendulumScene(),     CartPoleScene(false),       CartPoleScene(true),
      CartDoublePendulumScene(), DoublePendulumScene(false), DoublePendulumScene(true),
      UnicycleScene()};
  return *catalog;
}

const SceneDefinition* FindSceneDefinition(const std::string& name) {
  for (const SceneDefinition& s : SceneCatalog())
    if (s.name == name) return &s;
  return nullptr;
}

std::vector<std::string> SceneNames() {
  std::vector<std::string> names;
  for (const SceneDefinition& s : SceneCatalog()) names.push_back(s.name);
  return names;
}

std::string UnknownSceneText(const std::string& name) {
  const std::vector<std::string> names = SceneNames();
  std::vector<std::string> begun;
  for (const std::string& known : names)
    if (!name.empty() && known.rfind(name, 0) == 0) begun.push_back(known);
  if (begun.empty()) {
    const std::string closest = ClosestCandidate(name, names);
    if (!closest.empty()) begun.push_back(closest);
  }
  std::string text = absl::StrCat("unknown scene '", name, "' (");
  if (!begun.empty()) absl::StrAppend(&text, "did you mean ", absl::StrJoin(begun, " or "), "?; ");
  absl::StrAppend(&text, "known: ", absl::StrJoin(names, ", "), ")");
  return text;
}

absl::StatusOr<const SceneDefinition*> RunnableScene(const std::string& name,
                                                     const std::string& what) {
  const SceneDefinition* definition = FindSceneDefinition(name);
  if (definition == nullptr) return absl::InvalidArgumentError(UnknownSceneText(name));
  const std::string& unavailable = !definition->trials_unavailable.empty() || what != "studies"
                                       ? definition->trials_unavailable
                                       : definition->studies_unavailable;
  if (!unavailable.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("'", name, "' has no ", what, " yet: ", unavailable));
  }
  return definition;
}

std::unique_ptr<Plant> MakePlant(const SceneDefinition& d, const ode::IntegratorOptions& integrator) {
  switch (d.plant) {
    case PlantKind::kPendulum:
      return std::make_unique<tasks::Pendulum>(d.pendulum, d.dt, integrator);
    case PlantKind::kCartPole: {
      CartPoleParams params = d.cartpole;
      params.dt = d.dt;
      params.integrator = integrator;
      return std::make_unique<CartPole>(params);
    }
    case PlantKind::kCartDoublePendulum:
      return std::make_unique<CartDoublePendulum>(d.cart_double_pendulum, d.dt, integrator);
    case PlantKind::kDoublePendulum:
      return std::make_unique<DoublePendulum>(d.double_pendulum, d.dt, integrator);
    case PlantKind::kUnicycle:
      return std::make_unique<Unicycle>(d.unicycle, d.dt, integrator);
  }
  TG_CHECK(false);
  return nullptr;
}

Vector AugmentState(const Vector& x, const std::vector<int>& angle_indices) {
  const Eigen::Index d = x.size();
  Vector z(d + 2 * static_cast<Eigen::Index>(angle_indices.size()));
  z.head(d) = x;
  for (size_t a = 0; a < angle_indices.size(); ++a) {
    z(d + 2 * a) = std::sin(x(angle_indices[a]));
    z(d + 2 * a + 1) = std::cos(x(angle_indices[a]));
  }
  return z;
}

double PeakTrialBytes(const SceneDefinition& d, int particles) {
  const double n = static_cast<double>(d.horizon) * (d.learned_episodes + 1);
  const double support = std::min(n, static_cast<double>(d.inducing_inputs));
  const double outputs = d.learner_state_dim();
  const double gp = 8.0 * outputs * 2.0 * support * support + 8.0 * particles * n * outputs;
  const double e = d.learner_state_dim() + d.control_dim();
  const double rollout = 8.0 * particles * d.horizon * outputs * (2.0 * e + 6.0);
  return gp + rollout;
}

}  // namespace totalgrad::tasks
