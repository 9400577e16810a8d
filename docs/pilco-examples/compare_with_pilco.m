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
% gp/gp2d.m, util/{gTrig,gSat,gSin,maha,unwrap,rewrap}.m, loss/lossSat.m and
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

function out = compare_with_pilco(scenario_json, pilco_dir, out_json)
if nargin < 2 || isempty(pilco_dir), pilco_dir = getenv('PILCO_DIR'); end
if isempty(pilco_dir), error('compare_with_pilco: give pilco_dir or set PILCO_DIR'); end
if nargin < 3, out_json = ''; end
warning('off', 'all');                 % PILCO's util/unwrap.m shadows Octave's unwrap
addpath(fullfile(pilco_dir, 'base'), fullfile(pilco_dir, 'control'), ...
        fullfile(pilco_dir, 'gp'), fullfile(pilco_dir, 'util'), ...
        fullfile(pilco_dir, 'loss'), fullfile(pilco_dir, 'scenarios', 'cartPole'));

sc = jsondecode(fileread(scenario_json));
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
m = sc.mu0(:); S = sc.S0;
means = zeros(H + 1, D); means(1, :) = m';
covs = cell(1, H + 1); covs{1} = S;
cost_mean = zeros(1, H); cost_std = zeros(1, H);
for t = 1:H
  [m, S, dmdm, dSdm, dmdS, dSdS, dmdp, dSdp] = propagated(m, S, plant, dynmodel, policy);
  [L, dLdm, dLdS, S2] = cost.fcn(cost, m, S);
  means(t + 1, :) = full(m)'; covs{t + 1} = full(S);
  cost_mean(t) = L; cost_std(t) = sqrt(max(S2, 0));
end

% --- value.m: J and dJ in PILCO's parameterisation ----------------------------------------
[J, dJ] = value(policy.p, sc.mu0(:), sc.S0, dynmodel, policy, plant, cost, H);
Ep = numel(loglen);

out = struct();
out.mean = means;
out.cov = covs;
out.cost_mean = cost_mean;
out.cost_std = cost_std;
out.J = J;
out.J_loop = sum(cost_mean);
out.dJ_dcentres = dJ.inputs;
out.dJ_dtargets = dJ.targets(:)';
out.dJ_dlog_lengthscales = dJ.hyp(1:Ep)';
out.dJ_dhyp = dJ.hyp(:)';
out.targets = y';
out.parameterisation = 'pilco';
out.octave_version = version();

txt = jsonencode(out);
if isempty(out_json)
  fprintf('%s\n', txt);
else
  fid = fopen(out_json, 'w'); fprintf(fid, '%s\n', txt); fclose(fid);
end
end
