% compare_with_pilco.m -- run one `totalgrad pilco propagate` scenario through the ORIGINAL PILCO.
%
% Usage (GNU Octave >= 7, or MATLAB >= R2016b):
%   PILCO_DIR=/path/to/pilco-matlab octave --no-gui -q --eval \
%     "addpath('docs/pilco-examples'); compare_with_pilco('docs/pilco-examples/swingup_sincos_tip.json');"
%   compare_with_pilco(scenario_json, pilco_dir, out_json)   % pilco_dir / out_json optional
%
% This file is totalgrad's own driver; it contains no PILCO code. It needs a checkout of
% UCL-SML/pilco-matlab (given by the argument pilco_dir or the environment variable PILCO_DIR) and
% uses from it: base/value.m, base/propagated.m, control/conCat.m, control/congp.m, gp/gp0d.m,
% gp/gp1d.m (FITC), gp/gp2d.m, util/{gTrig,gSat,gSin,maha,unwrap,rewrap}.m, loss/lossSat.m and
% scenarios/cartPole/loss_cp.m.
%
% It reads a scenario in the format of docs/pilco.md section 2, builds PILCO's structures in the
% scenario's own state order (PILCO is generic in its indices: plant.angi = angle_index + 1,
% plant.poli = plant.dyni = [other state dims, sin, cos] or 1:D, plant.difi = 1:D), runs PILCO's
% propagation with derivatives step by step (propagated.m, accumulated as value.m does) for the
% trajectory, calls value.m itself for J and dJ, and writes one JSON object:
%   mean (H+1 x D), cov (H+1 x D x D), cost_mean (H), cost_std (H), J (value.m),
%   J_loop (the step loop's sum; must equal J),
%   dJ_dcentres (C x Ep) = value.m's dJ.inputs, dJ_dtargets (C) = dJ.targets,
%   dJ_dlog_lengthscales (Ep) = dJ.hyp(1:Ep), dJ_dhyp (all of dJ.hyp, sf/sn entries are 0),
%   targets (C): the pseudo-targets PILCO used; when the scenario gives our `weights` w, they are
%   y = (K_cc + 0.01^2 I) w with K_cc the policy's unit-signal SE kernel on the centres, so the
%   gradients above are in PILCO's parameterisation (pseudo-targets held fixed); compare.py
%   converts them to ours.
% Refused (error): prediction_includes_noise = true (gp0d predicts without noise),
% output_variance_jitter ~= 1e-6 (gp2d's jitter is fixed), a tip cost with position_index ~= 0
% (loss_cp reads the cart position from state 1).
%
% General form (a file with `angle_indices`, docs/pilco.md section 2 "General form"): PILCO's
% z = [x; sin x_a1; cos x_a1; sin x_a2; cos x_a2; ...] is gTrig's order (it appends a (sin, cos)
% pair per angle after the state), which is the file's z, so every 0-based index into z maps to
% PILCO's 1-based index + 1: plant.angi = angle_indices + 1, plant.dyni = dynamics_inputs + 1,
% plant.poli = policy_inputs + 1, plant.difi = plant.dyno = 1:D. The policy is
% conCat(@congp, @gSat) with policy.maxU = max_force (F numbers) and policy.p.hyp (Ep+2) x F,
% column j = [log l_j; 0; log 0.01] (the shared length-scales repeated in every column, or row j
% of a per-control F x Ep); policy.p.targets C x F (a `weights` file's y_j = (K_j + 0.01^2 I) w_j
% per column, K_j with that control's length-scales). The dynamics model is gp0d, or gp1d with
% dynmodel.induce = inducing_inputs (M x (Eq+F), shared by all outputs; gp1d adds its own ridge
% 1e-6 to Kmm). The cost is this file's general_loss (our code, not a PILCO function): z's
% Gaussian from gTrig with the cross-covariance s*C, lossSat on z with W = Q / w^2 and
% z = [target; sin/cos of the target's angles] per width, mean over the widths of the expected cost
% and of the variance (the variance as lossSat returns it, 0 below 1e-12), and its derivatives
% with respect to the state's m and s by the chain rule through gTrig's derivatives. Extra
% output fields for the general form: dJ_dlog_lengthscales in the file's shape (Ep: the sum over
% the F columns of dJ.hyp(1:Ep, :); F x Ep: dJ.hyp(1:Ep, :)'), dJ_dlog_lengthscales_per_control
% (F x Ep, always), dJ_dtargets and targets in the file's shape (C, or C x F), for a `targets`
% file weights_driver = (K_j + 0.01^2 I)^-1 y_j (solved here by Cholesky, as gp2d does), and
% form = 'general'.

function out = compare_with_pilco(scenario_json, pilco_dir, out_json)
if nargin < 2 || isempty(pilco_dir), pilco_dir = getenv('PILCO_DIR'); end
if isempty(pilco_dir), error('compare_with_pilco: give pilco_dir or set PILCO_DIR'); end
if nargin < 3, out_json = ''; end
warning('off', 'all');                 % PILCO's util/unwrap.m shadows Octave's unwrap
addpath(fullfile(pilco_dir, 'base'), fullfile(pilco_dir, 'control'), ...
        fullfile(pilco_dir, 'gp'), fullfile(pilco_dir, 'util'), ...
        fullfile(pilco_dir, 'loss'), fullfile(pilco_dir, 'scenarios', 'cartPole'));

sc = jsondecode(fileread(scenario_json));
if isfield(sc, 'angle_indices')        % general form: its own builder below
  out = general_form(sc);
  write_json(out, out_json);
  return;
end
D = size(sc.train_targets, 2);
H = sc.horizon;

% --- plant: indices into PILCO's augmented state [x (D); sin, cos of the angle; u; Delta] -----
if isempty(sc.angle_index) || sc.angle_index < 0
  angi = []; poli = 1:D;
else
  angi = sc.angle_index + 1;
  poli = [setdiff(1:D, angi), D+1, D+2];
end
plant.angi = angi; plant.poli = poli; plant.dyni = poli;
plant.difi = 1:D;                     % all targets are state differences
plant.dyno = 1:D;
plant.prop = @propagated;

% --- dynamics GP: hyp (E_in+2) x D = [log l; log sf; log sn] per output --------------------
if isfield(sc, 'prediction_includes_noise') && sc.prediction_includes_noise
  error('compare_with_pilco: prediction_includes_noise = true has no PILCO counterpart (gp0d)');
end
dynmodel.inputs = sc.train_inputs;
dynmodel.targets = sc.train_targets;
dynmodel.hyp = sc.gp_log_hyp';
dynmodel.fcn = @gp0d;

% --- policy: congp + gSat ------------------------------------------------------------------
pol = sc.policy;
if isfield(pol, 'output_variance_jitter') && abs(pol.output_variance_jitter - 1e-6) > 0
  error('compare_with_pilco: PILCO (gp2d) adds exactly 1e-6 output variance jitter');
end
centres = pol.centres;
if isvector(centres) && numel(poli) > 1 && size(centres, 2) ~= numel(poli)
  centres = reshape(centres, 1, []);  % a single centre decodes as a column
end
loglen = pol.log_lengthscales(:);
if isfield(pol, 'targets')
  y = pol.targets(:);
else                                  % our weights are beta: y = (K_cc + 1e-4 I) w
  w = pol.weights(:);
  z = bsxfun(@rdivide, centres, exp(loglen'));
  sq = bsxfun(@plus, sum(z.^2, 2), sum(z.^2, 2)') - 2 * (z * z');
  y = (exp(-sq / 2) + 1e-4 * eye(numel(w))) * w;
end
policy.maxU = pol.max_force;
policy.fcn = @(policy, m, s) conCat(@congp, @gSat, policy, m, s);
policy.p.inputs = centres;
policy.p.targets = y;
policy.p.hyp = [loglen; 0; log(0.01)];

% --- cost ----------------------------------------------------------------------------------
c = sc.cost;
cost.gamma = 1; cost.expl = 0;
switch c.type
  case 'tip'
    if c.position_index ~= 0
      error('compare_with_pilco: loss_cp needs the cart position at state index 0');
    end
    cost.fcn = @loss_cp;
    cost.p = c.pendulum_length;
    cost.width = c.width;
    cost.angle = c.angle_index + 1;
    target = zeros(D, 1);
    if isfield(c, 'target_position'), target(1) = c.target_position; end
    target(cost.angle) = pi;
    cost.target = target;
  case 'angle'
    cost.fcn = @lossSat;
    cost.z = c.target(:);
    Q = c.Q; if isvector(Q), Q = diag(Q(:)); end
    cost.W = 2 * Q;                   % ours: exp(-d'Qd); lossSat: exp(-d'Wd/2)
  otherwise
    error('compare_with_pilco: unknown cost type %s', c.type);
end

% --- step loop (trajectory and per-step cost), as value.m accumulates ---------------------
% --- and value.m: J and dJ in PILCO's parameterisation -----------------------------------
[out, dJ] = trajectory_and_value(sc, H, D, plant, dynmodel, policy, cost);
Ep = numel(loglen);
out.dJ_dcentres = dJ.inputs;
out.dJ_dtargets = dJ.targets(:)';
out.dJ_dlog_lengthscales = dJ.hyp(1:Ep)';
out.dJ_dhyp = dJ.hyp(:)';
out.targets = y';
out.parameterisation = 'pilco';
out.octave_version = version();

write_json(out, out_json);
end

function write_json(out, out_json)
txt = jsonencode(out);
if isempty(out_json)
  fprintf('%s\n', txt);
else
  fid = fopen(out_json, 'w'); fprintf(fid, '%s\n', txt); fclose(fid);
end
end

% --- general form ----------------------------------------------------------------------------
function out = general_form(sc)
D = size(sc.train_targets, 2);
H = sc.horizon;
angi = reshape(sc.angle_indices, 1, []) + 1;   % 0-based into x -> 1-based
A = numel(angi);
dyni = reshape(sc.dynamics_inputs, 1, []) + 1; % 0-based into z -> 1-based into PILCO's z
poli = reshape(sc.policy_inputs, 1, []) + 1;
Ep = numel(poli);

plant.angi = angi; plant.dyni = dyni; plant.poli = poli;
plant.difi = 1:D;                     % all targets are state differences
plant.dyno = 1:D;
plant.prop = @propagated;

if isfield(sc, 'prediction_includes_noise') && sc.prediction_includes_noise
  error(['compare_with_pilco: prediction_includes_noise = true has no PILCO counterpart ' ...
         '(gp0d/gp1d)']);
end
dynmodel.inputs = sc.train_inputs;
dynmodel.targets = sc.train_targets;
dynmodel.hyp = sc.gp_log_hyp';        % (Eq+F+2) x D
if isfield(sc, 'inducing_inputs')
  dynmodel.fcn = @gp1d;
  dynmodel.induce = sc.inducing_inputs; % M x (Eq+F), one set for every output
else
  dynmodel.fcn = @gp0d;
end

% --- policy: congp + gSat with F outputs ---------------------------------------------------
pol = sc.policy;
if isfield(pol, 'output_variance_jitter') && abs(pol.output_variance_jitter - 1e-6) > 0
  error('compare_with_pilco: PILCO (gp2d) adds exactly 1e-6 output variance jitter');
end
use_targets = isfield(pol, 'targets');
if use_targets, vals = pol.targets; else vals = pol.weights; end
vector_values = isvector(vals) && (size(vals, 2) == 1 || size(vals, 1) == 1) && ...
                numel(pol.max_force) == 1;
if vector_values, vals = vals(:); end
[C, F] = size(vals);
maxU = reshape(pol.max_force, 1, []);
if numel(maxU) ~= F
  error('compare_with_pilco: %d max forces for %d controls', numel(maxU), F);
end
centres = pol.centres;
if isvector(centres) && Ep > 1 && size(centres, 2) ~= Ep
  centres = reshape(centres, 1, []);  % a single centre decodes as a column
end
ll = pol.log_lengthscales;
shared = isvector(ll) && numel(ll) == Ep;
if shared
  loglen = repmat(ll(:), 1, F);       % Ep x F, one column per control
else
  loglen = ll';                       % file F x Ep -> Ep x F
end
y = zeros(C, F); w_used = zeros(C, F);
for j = 1:F
  z = bsxfun(@rdivide, centres, exp(loglen(:, j)'));
  sq = bsxfun(@plus, sum(z.^2, 2), sum(z.^2, 2)') - 2 * (z * z');
  Kj = exp(-sq / 2) + 1e-4 * eye(C);  % unit signal variance + congp's 0.01^2
  if use_targets
    y(:, j) = vals(:, j);
    Lj = chol(Kj)';
    w_used(:, j) = Lj' \ (Lj \ y(:, j));
  else                                % our weights are beta: y = (K_cc + 1e-4 I) w
    y(:, j) = Kj * vals(:, j);
    w_used(:, j) = vals(:, j);
  end
end
policy.maxU = maxU;
policy.fcn = @(policy, m, s) conCat(@congp, @gSat, policy, m, s);
policy.p.inputs = centres;
policy.p.targets = y;
policy.p.hyp = [loglen; zeros(1, F); log(0.01) * ones(1, F)];

% --- cost: lossSat on z, one W = Q / w^2 per width ----------------------------------------
c = sc.cost;
if ~strcmp(c.type, 'saturating')
  error('compare_with_pilco: the general form takes cost type saturating, not %s', c.type);
end
cost.fcn = @general_loss;
cost.gamma = 1;
cost.angi = angi;
cost.Q = c.Q;
cost.width = reshape(c.width, 1, []);
target = c.target(:);
if A > 0
  cost.zt = [target; gTrig(target, zeros(D), angi)];
else
  cost.zt = target;
end
if size(cost.Q, 1) ~= D + 2 * A
  error('compare_with_pilco: Q is %d x %d, z has %d entries', size(cost.Q), D + 2 * A);
end

% --- step loop and value.m, as for today's form -------------------------------------------
[out, dJ] = trajectory_and_value(sc, H, D, plant, dynmodel, policy, cost);

shape = @(M) M;
if vector_values, shape = @(M) M(:)'; end
out.form = 'general';
out.dJ_dcentres = dJ.inputs;
out.dJ_dtargets = shape(dJ.targets);
out.dJ_dlog_lengthscales_per_control = dJ.hyp(1:Ep, :)';
if shared
  out.dJ_dlog_lengthscales = sum(dJ.hyp(1:Ep, :), 2)';
else
  out.dJ_dlog_lengthscales = dJ.hyp(1:Ep, :)';
end
out.dJ_dhyp = dJ.hyp;
out.targets = shape(y);
if use_targets, out.weights_driver = shape(w_used); end
out.lengthscales_shared = shared;
out.parameterisation = 'pilco';
out.octave_version = version();
end

% Expected saturating cost of the general form and its derivatives with respect to the state's
% mean m (1 x D) and covariance s (1 x D^2, entries taken as independent, as value.m contracts
% them with the symmetric dS/dp). z = [x; gTrig(x)] with Cov(x, gTrig) = s*C; for each width,
% lossSat on z; then the chain rule from (M, S) of z back to (m, s).
function [L, dLdm, dLds, S2] = general_loss(cost, m, s)
D0 = numel(m); A = numel(cost.angi); D1 = D0 + 2 * A;
i = 1:D0; k = D0+1:D1;
M = zeros(D1, 1); M(i) = m;
S = zeros(D1); S(i, i) = s;
if A > 0
  [Mk, Sk, Ck, mdm, sdm, Cdm, mds, sds, Cds] = gTrig(m, s, cost.angi);
  M(k) = Mk; S(k, k) = Sk;
  X = s * Ck; S(i, k) = X; S(k, i) = X';
end
n = numel(cost.width);
L = 0; S2 = 0; gM = zeros(1, D1); gS = zeros(D1);
for r = 1:n
  lc.z = cost.zt; lc.W = cost.Q / cost.width(r)^2;
  [Lr, dLrdM, dLrdS, S2r] = lossSat(lc, M, S);
  L = L + Lr; S2 = S2 + S2r;
  gM = gM + dLrdM(:)'; gS = gS + reshape(dLrdS, D1, D1);
end
L = L / n; S2 = S2 / n; gM = gM / n; gS = gS / n;
% chain rule: M(i) = m, S(i,i) = s, M(k), S(k,k) from gTrig, S(i,k) = S(k,i)' = s*C(m, s)
dLdm = gM(i);
dLds = reshape(gS(i, i), 1, []);
if A > 0
  Gx = gS(i, k) + gS(k, i)';          % d L / d (s*C), both off-diagonal blocks
  GxS = reshape(s' * Gx, 1, []);      % vec(s' Gx)' = d L / d vec(C) at fixed s
  dLdm = dLdm + gM(k) * mdm + reshape(gS(k, k), 1, []) * sdm + GxS * Cdm;
  dLds = dLds + gM(k) * mds + reshape(gS(k, k), 1, []) * sds + GxS * Cds ...
         + reshape(Gx * Ck', 1, []);  % d L / d s through s*C at fixed C
end
end

% The trajectory and per-step cost, step by step with propagated.m and the cost, as value.m
% accumulates them, then value.m itself for J and dJ (both forms share it): out holds mean, cov,
% cost_mean, cost_std, J and J_loop (the step loop's sum, which must equal J).
function [out, dJ] = trajectory_and_value(sc, H, D, plant, dynmodel, policy, cost)
m = sc.mu0(:); S = sc.S0;
means = zeros(H + 1, D); means(1, :) = m';
covs = cell(1, H + 1); covs{1} = S;
cost_mean = zeros(1, H); cost_std = zeros(1, H);
for t = 1:H
  % All outputs asked for, as value.m asks: the derivative paths of propagated.m and the cost
  % are the ones being checked.
  [m, S, dmdm, dSdm, dmdS, dSdS, dmdp, dSdp] = propagated(m, S, plant, dynmodel, policy);
  [L, dLdm, dLdS, S2] = cost.fcn(cost, m, S);
  means(t + 1, :) = full(m)'; covs{t + 1} = full(S);
  cost_mean(t) = L; cost_std(t) = sqrt(max(S2, 0));
end
[J, dJ] = value(policy.p, sc.mu0(:), sc.S0, dynmodel, policy, plant, cost, H);
out = struct();
out.mean = means;
out.cov = covs;
out.cost_mean = cost_mean;
out.cost_std = cost_std;
out.J = J;
out.J_loop = sum(cost_mean);
end
