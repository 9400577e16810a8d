// What happened inside trials, for dashboard.js's job and sweep pages: the
// real trajectory of an episode against the model's prediction (mean, +-2
// std band) per state dimension, an animation of the scene replaying it
// (drawn from the scene's geometry), the estimator statistics per episode as
// small plots, per method over a sweep's trials, and a sweep's final
// episodes as small multiples marked with both verdicts. Data:
// /api/trajectory, /api/final_trajectories (io/trajectory_json.h's layout)
// and /api/diagnostics (server/dashboard/dashboard_data.h). Uses el, svg,
// fixed, ticks, api, state, refresh and curvePanel of dashboard.js (loaded
// after this file; called only once both are).
'use strict';

// The trajectory widget survives the page's refreshes (the animation keeps
// running): one per job, rebuilt only when another episode or rollout is
// chosen.
const trajectoryState = {job: null, episode: null, rollout: -1, node: null, timer: null};

// A line plot of series against x, with optional bands and a horizontal rule.
// series: [{values, colour, dash, label}], bands: [{low, high, colour}].
function smallPlot({title, xs, series, bands = [], rule = null, width = 300, height = 170, xLabel = '',
                    cssClass = 'small-plot', attributes = {}}) {
  const margin = {left: 46, right: 8, top: 20, bottom: xLabel ? 30 : 18};
  const plotW = width - margin.left - margin.right, plotH = height - margin.top - margin.bottom;
  const root = svg('svg', Object.assign({class: 'panel ' + cssClass, width, height,
                                         viewBox: `0 0 ${width} ${height}`}, attributes));
  root.append(svg('text', {class: 'title', x: 4, y: 13, text: title}));
  const finite = v => v !== null && v !== undefined && Number.isFinite(v);
  const ys = series.flatMap(s => s.values).concat(bands.flatMap(b => b.low.concat(b.high)))
      .concat(rule === null ? [] : [rule.value]).filter(finite);
  const xsFinite = xs.filter(finite);
  if (!ys.length || !xsFinite.length) {
    root.append(svg('text', {x: margin.left, y: margin.top + 24, text: 'no values'}));
    return root;
  }
  let yMin = Math.min(...ys), yMax = Math.max(...ys);
  if (yMin === yMax) { yMin -= 1; yMax += 1; }
  const pad = (yMax - yMin) * 0.05;
  yMin -= pad; yMax += pad;
  let xMin = Math.min(...xsFinite), xMax = Math.max(...xsFinite);
  if (xMin === xMax) { xMin -= 1; xMax += 1; }
  const x = v => margin.left + (v - xMin) / (xMax - xMin) * plotW;
  const y = v => margin.top + (1 - (v - yMin) / (yMax - yMin)) * plotH;
  const axis = svg('g', {class: 'axis'});
  for (const t of ticks(yMin, yMax, 3)) {
    if (t < yMin || t > yMax) continue;
    axis.append(svg('line', {class: 'grid', x1: margin.left, x2: margin.left + plotW, y1: y(t), y2: y(t)}));
    axis.append(svg('text', {x: margin.left - 4, y: y(t) + 4, 'text-anchor': 'end', text: +t.toPrecision(4)}));
  }
  for (const t of ticks(xMin, xMax, 4)) {
    if (t < xMin || t > xMax) continue;
    axis.append(svg('text', {x: x(t), y: margin.top + plotH + 12, 'text-anchor': 'middle', text: +t.toPrecision(4)}));
  }
  if (xLabel) {
    axis.append(svg('text', {x: margin.left + plotW / 2, y: height - 4, 'text-anchor': 'middle', text: xLabel}));
  }
  axis.append(svg('rect', {x: margin.left, y: margin.top, width: plotW, height: plotH, fill: 'none', stroke: '#90a4ae'}));
  root.append(axis);
  for (const b of bands) {
    const idx = xs.map((_, i) => i).filter(i => finite(b.low[i]) && finite(b.high[i]));
    if (!idx.length) continue;
    const points = idx.map(i => `${x(xs[i])},${y(b.high[i])}`)
        .concat(idx.slice().reverse().map(i => `${x(xs[i])},${y(b.low[i])}`)).join(' ');
    root.append(svg('polygon', {class: 'band', points, fill: b.colour, 'fill-opacity': 0.18, stroke: 'none'}));
  }
  if (rule !== null) {
    root.append(svg('line', {class: 'threshold', x1: margin.left, x2: margin.left + plotW,
                             y1: y(rule.value), y2: y(rule.value)}, svg('title', {text: rule.label})));
  }
  for (const s of series) {
    const pts = xs.map((xv, i) => [xv, s.values[i]]).filter(([a, b]) => finite(a) && finite(b));
    root.append(svg('polyline', {class: 'series', 'data-label': s.label, fill: 'none', stroke: s.colour,
                                 'stroke-width': 1.6, 'stroke-dasharray': s.dash || null,
                                 points: pts.map(([a, b]) => `${x(a)},${y(b)}`).join(' ')},
                    svg('title', {text: s.label})));
  }
  return root;
}

// The scene at time step t, drawn from its geometry: a cart (when there is
// one) and links hanging from it at their angles (0 = hanging down).
function drawScene(root, data, t) {
  const g = data.geometry;
  const states = data.states;
  const reach = g.links.reduce((sum, l) => sum + l.length, 0) || 1;
  const cartXs = g.cart === null ? [0] : states.map(s => s[g.cart]).filter(v => v !== null);
  const xLow = Math.min(...cartXs) - reach * 1.1, xHigh = Math.max(...cartXs) + reach * 1.1;
  const width = Number(root.getAttribute('width')), height = Number(root.getAttribute('height'));
  const scale = Math.min(width / (xHigh - xLow), height / (2.4 * reach));
  const originY = height / 2;
  const px = v => (v - xLow) * scale, py = v => originY - v * scale;
  root.replaceChildren();
  root.append(svg('line', {x1: 0, x2: width, y1: py(0), y2: py(0), stroke: '#cfd8dc'}));
  // Where the tip belongs at the goal (upright above the origin).
  root.append(svg('circle', {cx: px(0), cy: py(reach), r: 4, fill: 'none', stroke: '#2e7d32'}));
  const state = states[t];
  let ax = g.cart === null ? 0 : state[g.cart], ay = 0;
  if (g.cart !== null) {
    root.append(svg('rect', {class: 'cart', x: px(ax) - 18, y: py(0) - 9, width: 36, height: 18,
                             fill: '#546e7a'}));
  }
  for (const link of g.links) {
    const angle = state[link.angle];
    const bx = ax + link.length * Math.sin(angle), by = ay - link.length * Math.cos(angle);
    root.append(svg('line', {class: 'link', x1: px(ax), y1: py(ay), x2: px(bx), y2: py(by),
                             stroke: '#c62828', 'stroke-width': 5, 'stroke-linecap': 'round'}));
    ax = bx; ay = by;
  }
  root.append(svg('circle', {cx: px(ax), cy: py(ay), r: 4, fill: '#263238'}));
  root.append(svg('text', {x: 6, y: 14, text: `t = ${fixed(t * data.dt, 2)} s (step ${t})`}));
  root.setAttribute('data-frame', t);
}

function animation(data) {
  const stage = svg('svg', {class: 'panel scene', id: 'scene', width: 420, height: 240, viewBox: '0 0 420 240'});
  const last = data.states.length - 1;
  const slider = el('input', {type: 'range', id: 'scene-time', min: 0, max: last, value: 0,
                              oninput: e => { pause(); drawScene(stage, data, Number(e.target.value)); }});
  const button = el('button', {id: 'scene-play', type: 'button', text: 'play'});
  function pause() {
    clearInterval(trajectoryState.timer);
    trajectoryState.timer = null;
    button.textContent = 'play';
  }
  button.addEventListener('click', () => {
    if (trajectoryState.timer !== null) { pause(); return; }
    if (Number(slider.value) >= last) slider.value = 0;
    button.textContent = 'pause';
    trajectoryState.timer = setInterval(() => {
      const t = Math.min(last, Number(slider.value) + 1);
      slider.value = t;
      drawScene(stage, data, t);
      if (t >= last) pause();
    }, Math.max(40, 1000 * (data.dt || 0.1)));
  });
  drawScene(stage, data, 0);
  return el('div', {class: 'animation'}, stage, el('div', {class: 'controls'}, button, ' ', slider));
}

function trajectoryPlots(data) {
  const xs = data.states.map((_, t) => t * data.dt);
  const plots = data.state_names.map((name, m) => {
    const series = [{values: data.states.map(s => s[m]), colour: '#c62828',
                     label: data.rollout === undefined ? 'real episode' : `verdict rollout ${data.rollout}`}];
    const bands = [];
    if (data.predicted_mean.length === data.states.length) {
      const mean = data.predicted_mean.map(r => r[m]), std = data.predicted_std.map(r => r[m]);
      series.push({values: mean, colour: '#1565c0', dash: '5 3', label: 'model prediction (mean)'});
      bands.push({low: mean.map((v, i) => v - 2 * std[i]), high: mean.map((v, i) => v + 2 * std[i]),
                  colour: '#1565c0'});
    }
    return smallPlot({title: name, xs, series, bands, xLabel: 'time (s)', cssClass: 'state-plot',
                      attributes: {'data-state': name}});
  });
  plots.push(smallPlot({title: 'distance from the goal', xs,
                        series: [{values: data.goal_distance, colour: '#37474f', label: 'goal distance'}],
                        rule: {value: data.verdict_distance, label: `verdict distance ${data.verdict_distance}`},
                        xLabel: 'time (s)', cssClass: 'state-plot'}));
  return el('div', {class: 'plots', id: 'trajectory-plots'}, ...plots);
}

async function buildTrajectoryWidget(jobId, episode, rollout) {
  const query = `/api/trajectory?id=${encodeURIComponent(jobId)}&episode=${episode}` +
                (rollout >= 0 ? `&rollout=${rollout}` : '');
  const data = await api(query);
  const episodePicker = el('select', {id: 'trajectory-episode', onchange: e => {
    trajectoryState.episode = Number(e.target.value); trajectoryState.rollout = -1; trajectoryState.node = null; refresh(); }},
    ...data.episodes_recorded.map(e => el('option', {value: e, text: `episode ${e}`, selected: e === episode})));
  const rolloutPicker = data.verdict_rollouts > 0 ? el('select', {id: 'trajectory-rollout', onchange: e => {
    trajectoryState.rollout = Number(e.target.value); trajectoryState.node = null; refresh(); }},
    el('option', {value: -1, text: 'the real episode', selected: rollout < 0}),
    ...Array.from({length: data.verdict_rollouts}, (_, r) =>
        el('option', {value: r, text: `verdict rollout ${r}`, selected: r === rollout}))) : null;
  return el('div', {id: 'trajectory'},
      el('div', {class: 'controls'}, el('label', {}, 'show ', episodePicker), rolloutPicker ? el('label', {}, rolloutPicker) : null,
         el('span', {class: 'muted', text: `real cost ${fixed(data.real_cost, 3)}; red: what happened, ` +
             'blue: the model\'s prediction of the optimised policy (mean ± 2 std)'})),
      animation(data), trajectoryPlots(data));
}

// The job page's trajectory section: null when the job recorded none.
async function trajectorySection(jobId, lastEpisode) {
  if (trajectoryState.job !== jobId) {
    clearInterval(trajectoryState.timer);
    Object.assign(trajectoryState, {job: jobId, episode: lastEpisode, rollout: -1, node: null, timer: null});
  }
  if (trajectoryState.node === null) {
    try {
      trajectoryState.node = await buildTrajectoryWidget(jobId, trajectoryState.episode, trajectoryState.rollout);
    } catch (error) {
      return el('p', {class: 'muted', id: 'trajectory-missing', text: 'no trajectory: ' + error.message});
    }
  }
  return trajectoryState.node;
}

// The estimator statistics of a job's episodes (the final attempt's).
const STATISTICS = [
  ['gradient_norm_mean', 'gradient norm (mean over steps)'],
  ['gradient_snr_mean', 'gradient SNR (mean over steps)'],
  ['step_norm_mean', 'step norm (mean over steps)'],
  ['ess_median', 'importance weights: ESS median'],
  ['ess_low_fraction', 'fraction of steps with ESS < P/10'],
];

function statisticsPlots(episodes) {
  const final = episodes.filter(e => e.final_attempt).sort((a, b) => a.episode - b.episode);
  const plots = STATISTICS.filter(([key]) => final.some(e => e[key] !== null && e[key] !== undefined))
      .map(([key, title]) => smallPlot({title, xs: final.map(e => e.episode),
                                        series: [{values: final.map(e => e[key]), colour: '#6a1b9a', label: key}],
                                        xLabel: 'episode', cssClass: 'statistic-plot', attributes: {'data-statistic': key}}));
  return plots.length ? el('div', {class: 'plots', id: 'statistics'}, ...plots) : null;
}

// A sweep's final episodes as small multiples: the goal distance against
// time, the verdict distance and hold window, the threshold verdict (frame:
// green success, red not) and the rollout verdict (held / not held).
function finalTrajectories(data) {
  if (!data.trials.length) {
    return el('p', {class: 'muted', id: 'final-trajectories', text: data.without ?
        `${data.without} completed trials recorded no trajectories (run by a build before them)` : 'no completed trial yet'});
  }
  const multiples = data.trials.map(trial => {
    const xs = trial.goal_distance.map((_, t) => t * trial.dt);
    const held = trial.held_fraction === null ? null : trial.held_fraction >= 0.5;
    const plot = smallPlot({
      title: `${trial.method} s${trial.seed}${trial.variant ? ' ' + trial.variant : ''}`,
      xs, series: [{values: trial.goal_distance, colour: '#37474f', label: 'goal distance'}],
      rule: {value: trial.verdict_distance, label: `verdict distance ${trial.verdict_distance}`},
      width: 170, height: 110, cssClass: 'multiple',
      attributes: {'data-job': trial.job, 'data-success': trial.success, 'data-held': held}});
    plot.classList.add(trial.success ? 'success' : 'failure');
    plot.append(svg('text', {x: 166, y: 13, 'text-anchor': 'end', class: held ? 'held' : 'not-held',
                             text: held === null ? '' : held ? 'held' : 'fell'},
                    svg('title', {text: `rollouts held ${fixed(trial.held_fraction, 2)}; final cost ${fixed(trial.final_eval_cost, 2)}`})));
    return el('a', {href: '#/job/' + trial.job}, plot);
  });
  return el('div', {id: 'final-trajectories'},
      el('p', {class: 'muted', text: 'Each trial\'s final episode: distance of the tip from the goal against time, ' +
          'the rollout verdict\'s distance dashed. Frame green: final cost below the threshold; "held"/"fell": ' +
          'the rollout verdict.' + (data.without ? ` ${data.without} trials recorded no trajectories.` : '')}),
      el('div', {class: 'plots'}, ...multiples));
}

// The sweep page's estimator statistic per method and episode (one curve
// panel per variant, /api/diagnostics), with a picker of the statistic.
function diagnosticsPanels(data) {
  const picker = el('select', {id: 'statistic', onchange: e => { state.statistic = e.target.value; refresh(); }},
      ...data.statistics.map(name => el('option', {value: name, text: name, selected: name === data.statistic})));
  return el('div', {id: 'diagnostics'},
      el('div', {class: 'controls'}, el('label', {}, 'statistic ', picker),
         el('span', {class: 'muted', text: 'formulas: docs/diagnostics.md'})),
      data.panels.length ? el('div', {class: 'plots'}, ...data.panels.map(curvePanel))
                         : el('p', {class: 'muted', text: `no completed trial recorded ${data.statistic}`}));
}
