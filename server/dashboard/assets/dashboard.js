// The totalgrad dashboard: a read-only view of the coordinator's store.
// Views (by URL fragment): #/ sweeps and workers; #/sweep/NAME progress,
// success table, learning curves, comparisons, estimator statistics, final
// episodes, jobs; #/job/ID episodes, trajectories and statistics
// (inside_trials.js), logs; #/table1/NAME,NAME... the paper's Table 1 from
// those sweeps.
// Data come from the coordinator's /api/* (server/dashboard/dashboard.h),
// statistics named as in `totalgrad results ... -f json` (results/);
// every text from the store is put in the page as text, never as markup.
'use strict';

const REFRESH_MS = 3000;
const TOKEN_KEY = 'totalgrad-user-token';
const SVG_NS = 'http://www.w3.org/2000/svg';

const state = {
  includeRunning: true,  // curves: running trials' episodes too
  baseline: '',          // comparisons: '' = every pair
  statistic: 'gradient_snr_mean',  // the estimator statistic drawn per method
  table1Sweeps: new Set(),  // overview: the sweeps checked for the paper's Table 1
  timer: null,
  generation: 0,         // a render that finished after a newer one started is dropped
};

// ---- small helpers ----

function el(tag, attributes, ...children) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key === 'class') node.className = value;
    else if (key === 'text') node.textContent = value;
    else if (key.startsWith('on')) node.addEventListener(key.slice(2), value);
    else node.setAttribute(key, value === true ? '' : String(value));
  }
  for (const child of children) {
    if (child === null || child === undefined) continue;
    node.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
  return node;
}

function svg(tag, attributes, ...children) {
  const node = document.createElementNS(SVG_NS, tag);
  for (const [key, value] of Object.entries(attributes || {})) {
    if (value === undefined || value === null) continue;
    if (key === 'text') node.textContent = value;
    else node.setAttribute(key, String(value));
  }
  for (const child of children) if (child) node.append(child);
  return node;
}

function fixed(value, digits) {
  return value === null || value === undefined || Number.isNaN(value) ? '–' : Number(value).toFixed(digits);
}

function signed(value, digits) {
  if (value === null || value === undefined) return '–';
  const text = Number(value).toFixed(digits);
  return value > 0 ? '+' + text : text;
}

function pValue(p) {
  if (p === null || p === undefined) return '–';
  return p < 0.001 ? '<0.001' : p.toFixed(3);
}

function duration(seconds) {
  if (seconds === null || seconds === undefined) return '–';
  if (seconds < 90) return Math.round(seconds) + ' s';
  if (seconds < 5400) return Math.round(seconds / 60) + ' min';
  if (seconds < 172800) return (seconds / 3600).toFixed(1) + ' h';
  return (seconds / 86400).toFixed(1) + ' days';
}

function when(ms) {
  return ms ? new Date(ms).toLocaleString() : '–';
}

function stateSpan(name) {
  return el('span', {class: 'state-' + name, text: name});
}

// ---- the API ----

class Unauthorized extends Error {}

async function api(path) {
  const headers = {};
  const token = sessionStorage.getItem(TOKEN_KEY);
  if (token) headers['Authorization'] = 'Bearer ' + token;
  const response = await fetch(path, {headers, cache: 'no-store'});
  if (response.status === 401 || response.status === 403) {
    const body = await response.json().catch(() => ({}));
    throw new Unauthorized(body.error || response.statusText);
  }
  const body = await response.json().catch(() => null);
  if (!response.ok) {
    throw new Error((body && body.error) || `${response.status} ${response.statusText}`);
  }
  return body;
}

function showLogin(message) {
  document.getElementById('login').hidden = false;
  document.getElementById('login-error').textContent =
      sessionStorage.getItem(TOKEN_KEY) ? message : '';
  document.getElementById('view').replaceChildren(
      el('p', {class: 'muted', text: 'The dashboard needs the user token.'}));
}

// ---- progress ----

function progressBar(sweep) {
  const expected = Math.max(1, sweep.episodes_expected);
  const stored = sweep.episodes_stored;
  const bar = el('span', {class: 'bar', title: `${stored} of ${sweep.episodes_expected} episodes stored`});
  const done = el('span', {class: 'completed'});
  done.style.width = (100 * stored / expected).toFixed(2) + '%';
  bar.append(done);
  return el('span', {class: 'progress'}, bar,
            el('span', {class: 'progress-text', 'data-episodes': stored,
                        text: `${stored}/${sweep.episodes_expected} episodes`}));
}

function jobCounts(sweep) {
  const parts = [`${sweep.jobs_completed}/${sweep.jobs_total} jobs done`];
  if (sweep.jobs_running) parts.push(`${sweep.jobs_running} running`);
  if (sweep.jobs_queued) parts.push(`${sweep.jobs_queued} queued`);
  if (sweep.jobs_failed) parts.push(`${sweep.jobs_failed} failed`);
  if (sweep.jobs_cancelled) parts.push(`${sweep.jobs_cancelled} cancelled`);
  return parts.join(', ');
}

// "completed" / "finished" (some jobs failed or were cancelled) once nothing
// is queued or running, else the stored state (running, paused, cancelled).
function sweepState(sweep) {
  if (!sweep.finished) return sweep.state;
  return sweep.jobs_completed === sweep.jobs_total ? 'completed' : 'finished';
}

function etaText(sweep) {
  if (sweep.finished) return 'finished';
  const eta = sweep.eta || {};
  return eta.known ? '≈ ' + duration(eta.seconds) : 'unknown';
}

// ---- views ----

async function renderOverview(view) {
  const data = await api('/api/overview');
  document.getElementById('build').textContent = `coordinator ${data.build}; database ${data.database}`;
  const rows = data.sweeps.map(s => el('tr', {'data-sweep': s.name},
      el('td', {}, el('input', {type: 'checkbox', class: 'table1-pick', title: 'include in the paper\'s Table 1',
                                checked: state.table1Sweeps.has(s.name),
                                onchange: e => { if (e.target.checked) state.table1Sweeps.add(s.name);
                                                 else state.table1Sweeps.delete(s.name); }})),
      el('td', {}, el('a', {href: '#/sweep/' + encodeURIComponent(s.name), text: s.name})),
      el('td', {}, stateSpan(sweepState(s))),
      el('td', {}, progressBar(s)),
      el('td', {text: jobCounts(s)}),
      el('td', {class: 'eta', title: (s.eta && s.eta.basis) || '', text: etaText(s)}),
      el('td', {text: when(s.created_unix_ms)}),
      el('td', {class: 'muted', text: s.description})));
  const sweeps = rows.length
      ? el('table', {id: 'sweeps'},
           el('thead', {}, el('tr', {}, ...['Table 1', 'sweep', 'state', 'progress', 'jobs', 'time to finish',
                                             'submitted', 'description'].map(t => el('th', {text: t})))),
           el('tbody', {}, ...rows))
      : el('p', {class: 'muted', text: 'No sweep yet: submit one with `totalgrad sweep submit FILE`.'});
  const workers = data.workers.length
      ? el('table', {id: 'workers'},
           el('thead', {}, el('tr', {}, ...['worker', 'state', 'host', 'slots', 'running', 'last seen', 'build']
                                            .map(t => el('th', {text: t})))),
           el('tbody', {}, ...data.workers.map(w => el('tr', {},
               el('td', {text: w.id}), el('td', {}, stateSpan(w.state)), el('td', {text: w.host}),
               el('td', {class: 'num', text: w.slots}), el('td', {class: 'num', text: w.running}),
               el('td', {text: when(w.last_seen_ms)}), el('td', {class: 'muted', text: w.build})))))
      : el('p', {class: 'muted', text: 'No worker has called in yet.'});
  const table1Button = data.sweeps.length
      ? el('p', {}, el('button', {id: 'table1-open', type: 'button', onclick: () => {
            const names = data.sweeps.map(s => s.name).filter(n => state.table1Sweeps.has(n));
            if (names.length) location.hash = '#/table1/' + names.map(encodeURIComponent).join(',');
          }}, 'The paper\'s Table 1 from the checked sweeps'))
      : null;
  view.replaceChildren(el('h2', {text: 'Sweeps'}), sweeps, table1Button, el('h2', {text: 'Workers'}), workers);
}

function table1(data) {
  const {methods, variants, cells} = data.table;
  if (!cells.length) return el('p', {class: 'muted', id: 'table1-empty', text: 'No trial has completed yet.'});
  const byKey = new Map(cells.map(c => [c.method + '\u0000' + c.variant, c]));
  return el('table', {id: 'table1'},
      el('thead', {}, el('tr', {}, el('th', {text: 'method'}),
          ...variants.map(v => el('th', {text: v || 'all trials'})))),
      el('tbody', {}, ...methods.map(m => el('tr', {'data-method': m}, el('th', {text: m}),
          ...variants.map(v => {
            const c = byKey.get(m + '\u0000' + v);
            if (!c) return el('td', {class: 'muted', text: '–'});
            return el('td', {'data-variant': v},
                el('div', {class: 'cell-rate',
                           text: `${fixed(c.success_rate, 2)} [${fixed(c.wilson95_low, 2)}, ${fixed(c.wilson95_high, 2)}] n=${c.trials}`}),
                el('div', {class: 'cell-sub', text: `median final cost ${fixed(c.median_final_cost, 2)}`}),
                c.classified > 0 ? el('div', {class: 'cell-sub cell-held',
                    text: `rollout verdict: held ${c.held}/${c.classified} [${fixed(c.held_wilson95_low, 2)}, ${fixed(c.held_wilson95_high, 2)}]`}) : null);
          })))));
}

async function renderTable1(view, names) {
  const data = await api('/api/table1?' + names.map(n => 'name=' + encodeURIComponent(n)).join('&'));
  view.replaceChildren(
      el('h2', {text: 'Table 1 (Parmas et al. 2018) from ' + names.join(', ')}),
      el('p', {class: 'muted', text: 'Success rate [95% Wilson interval] n=trials; held: the rollout verdict ' +
          '(trials whose final policy held in at least half of its verdict rollouts, of those classified); ' +
          'paper: the paper\'s success rate, in or OUT of our interval. Trials of several sweeps in one cell are pooled.'}),
      ...paperTable1(data));
  setCrumbs([['#/', 'sweeps'], [null, 'Table 1']]);
}

// Round tick values covering [low, high].
function ticks(low, high, count) {
  if (!(high > low)) { high = low + 1; low = low - 1; }
  const raw = (high - low) / count;
  const magnitude = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 2.5, 5, 10].map(f => f * magnitude).find(s => s >= raw);
  const out = [];
  for (let t = Math.ceil(low / step) * step; t <= high + step * 1e-9; t += step) out.push(+t.toFixed(10));
  return out;
}

// One panel: quartile bands, median curves, the threshold, a legend with n.
function curvePanel(panel) {
  // The legend sits right of the plot: costs fall from the top left, and
  // any corner inside would hide some curve.
  const width = 560, height = 320;
  const margin = {left: 52, right: 136, top: 26, bottom: 38};
  const plotW = width - margin.left - margin.right, plotH = height - margin.top - margin.bottom;
  const root = svg('svg', {class: 'panel', width, height, viewBox: `0 0 ${width} ${height}`,
                           'data-variant': panel.variant});
  root.append(svg('text', {class: 'title', x: margin.left, y: 16, text: panel.title}));
  const points = panel.methods.flatMap(m => m.points);
  if (!points.length) {
    root.append(svg('text', {x: margin.left, y: margin.top + 30, text: 'no evaluated episode yet'}));
    return root;
  }
  let xMin = Math.min(...points.map(p => p.episode)), xMax = Math.max(...points.map(p => p.episode));
  if (xMin === xMax) { xMin -= 1; xMax += 1; }
  const ys = points.flatMap(p => [p.q25, p.q75, p.median]).filter(v => v !== null);
  if (panel.threshold !== null) ys.push(panel.threshold);
  let yMin = Math.min(...ys), yMax = Math.max(...ys);
  const pad = (yMax - yMin) * 0.05 || 1;
  yMin -= pad; yMax += pad;
  const x = e => margin.left + (e - xMin) / (xMax - xMin) * plotW;
  const y = v => margin.top + (1 - (v - yMin) / (yMax - yMin)) * plotH;

  const axis = svg('g', {class: 'axis'});
  for (const t of ticks(yMin, yMax, 5)) {
    if (t < yMin || t > yMax) continue;
    axis.append(svg('line', {class: 'grid', x1: margin.left, x2: margin.left + plotW, y1: y(t), y2: y(t)}));
    axis.append(svg('text', {x: margin.left - 6, y: y(t) + 4, 'text-anchor': 'end', text: +t.toPrecision(6)}));
  }
  for (const t of ticks(xMin, xMax, Math.min(10, xMax - xMin))) {
    if (t < xMin || t > xMax || !Number.isInteger(t)) continue;
    axis.append(svg('text', {x: x(t), y: margin.top + plotH + 14, 'text-anchor': 'middle', text: t}));
  }
  axis.append(svg('rect', {x: margin.left, y: margin.top, width: plotW, height: plotH,
                           fill: 'none', stroke: '#90a4ae'}));
  axis.append(svg('text', {x: margin.left + plotW / 2, y: height - 6, 'text-anchor': 'middle', text: 'episode'}));
  axis.append(svg('text', {x: 12, y: margin.top + plotH / 2, 'text-anchor': 'middle',
                           transform: `rotate(-90 12 ${margin.top + plotH / 2})`, text: panel.y_label || 'evaluation cost'}));
  root.append(axis);

  for (const m of panel.methods) {
    const pts = m.points.filter(p => p.median !== null);
    if (!pts.length) continue;
    const band = pts.map(p => `${x(p.episode)},${y(p.q75)}`)
        .concat(pts.slice().reverse().map(p => `${x(p.episode)},${y(p.q25)}`)).join(' ');
    root.append(svg('polygon', {class: 'band', points: band, fill: m.colour, 'fill-opacity': 0.16,
                                stroke: 'none', 'data-method': m.method}));
  }
  for (const m of panel.methods) {
    const pts = m.points.filter(p => p.median !== null);
    if (!pts.length) continue;
    const curve = svg('polyline', {class: 'curve', 'data-method': m.method, fill: 'none', stroke: m.colour,
                                   'stroke-width': 2, points: pts.map(p => `${x(p.episode)},${y(p.median)}`).join(' ')});
    root.append(curve);
    for (const p of pts) {
      root.append(svg('circle', {cx: x(p.episode), cy: y(p.median), r: 2.5, fill: m.colour},
          svg('title', {text: `${m.method}, episode ${p.episode}: median ${fixed(p.median, 3)}, ` +
                              `quartiles ${fixed(p.q25, 3)}–${fixed(p.q75, 3)}, n=${p.n}`})));
    }
  }
  const legend = svg('g', {class: 'legend'});
  let row = 0;
  const legendX = margin.left + plotW + 14, legendY = margin.top + 8;
  const entries = panel.methods.map(m => ({label: `${m.method} (n=${m.trials})`, colour: m.colour, dash: null}));
  if (panel.threshold !== null) {
    const yT = y(panel.threshold);
    root.append(svg('line', {class: 'threshold', x1: margin.left, x2: margin.left + plotW, y1: yT, y2: yT}));
    entries.push({label: `success below ${panel.threshold}`, colour: '#555', dash: '6 4'});
  }
  legend.append(svg('rect', {x: legendX - 6, y: legendY - 9, width: 122, height: entries.length * 14 + 6,
                             fill: '#fff', 'fill-opacity': 0.85, stroke: '#cfd8dc'}));
  for (const entry of entries) {
    const yy = legendY + row * 14;
    legend.append(svg('line', {x1: legendX, x2: legendX + 18, y1: yy - 3, y2: yy - 3, stroke: entry.colour,
                               'stroke-width': 2, 'stroke-dasharray': entry.dash}));
    legend.append(svg('text', {x: legendX + 22, y: yy + 1, text: entry.label}));
    row++;
  }
  root.append(legend);
  return root;
}

// Which paired test found what, as the CLI's verdict columns say it.
function verdictText(c) {
  const parts = [];
  if (c.success_verdict && c.success_verdict !== 'no evidence') parts.push('success (McNemar): ' + c.success_verdict);
  if (c.cost_verdict && c.cost_verdict !== 'no evidence') parts.push('cost (Wilcoxon): ' + c.cost_verdict);
  return parts.length ? parts.join('; ') : 'no evidence';
}

function compareTable(data) {
  if (!data.comparisons.length) {
    return el('p', {class: 'muted', text: 'Nothing to compare yet: no task variant has completed trials of two methods.'});
  }
  const alpha = data.alpha;
  const head = ['variant', 'method', 'vs', 'pairs', 'only method / only vs', 'Δ success', 'McNemar p (Holm)',
                'power', 'cost shift (HL)', 'rank-biserial', 'Wilcoxon p (Holm)', 'power', 'rates',
                'Fisher p (Holm)', 'power', 'verdict'];
  return el('table', {id: 'compare'},
      el('thead', {}, el('tr', {}, ...head.map(t => el('th', {text: t})))),
      el('tbody', {}, ...data.comparisons.map(c => {
        const significant = (c.mcnemar_p_holm !== null && c.mcnemar_p_holm < alpha) ||
                            (c.wilcoxon_p_holm !== null && c.wilcoxon_p_holm < alpha);
        return el('tr', {class: significant ? 'significant' : null},
            el('td', {text: c.variant || 'all trials'}), el('td', {text: c.method}), el('td', {text: c.vs}),
            el('td', {class: 'num', text: c.pairs}),
            el('td', {class: 'num', text: `${c.method_only} / ${c.vs_only}`}),
            el('td', {class: 'num', text: signed(c.success_difference, 2)}),
            el('td', {class: 'num', text: `${pValue(c.mcnemar_p)} (${pValue(c.mcnemar_p_holm)})`}),
            el('td', {class: 'num', text: fixed(c.mcnemar_power, 2)}),
            el('td', {class: 'num', text: signed(c.cost_shift_hl, 3)}),
            el('td', {class: 'num', text: signed(c.rank_biserial, 2)}),
            el('td', {class: 'num', text: `${pValue(c.wilcoxon_p)} (${pValue(c.wilcoxon_p_holm)})` +
                                          (c.wilcoxon_exact ? '' : ' normal')}),
            el('td', {class: 'num', text: fixed(c.wilcoxon_power, 2)}),
            el('td', {class: 'num', text: `${c.method_successes}/${c.method_trials} vs ${c.vs_successes}/${c.vs_trials}`}),
            el('td', {class: 'num', text: `${pValue(c.fisher_p)} (${pValue(c.fisher_p_holm)})`}),
            el('td', {class: 'num', text: fixed(c.fisher_power, 2)}),
            el('td', {class: 'verdict', text: verdictText(c)}));
      })));
}

function jobsTable(jobs) {
  return el('table', {id: 'jobs'},
      el('thead', {}, el('tr', {}, ...['job', 'method', 'seed', 'variant', 'state', 'episodes', 'attempts',
                                        'worker', 'final cost', 'success', 'held', 'last error'].map(t => el('th', {text: t})))),
      el('tbody', {}, ...jobs.map(j => el('tr', {'data-job': j.job_id},
          el('td', {}, el('a', {href: '#/job/' + j.job_id, text: j.job_id})),
          el('td', {text: j.method}), el('td', {text: j.seed}), el('td', {text: j.variant}),
          el('td', {}, stateSpan(j.state)),
          el('td', {class: 'num', text: `${j.episodes_stored}/${j.episodes_expected}`}),
          el('td', {class: 'num', text: j.attempts}), el('td', {text: j.worker_id}),
          el('td', {class: 'num', text: j.state === 'completed' ? fixed(j.final_eval_cost, 3) : ''}),
          el('td', {text: j.state !== 'completed' ? '' : (j.success ? 'yes' : 'no')}),
          el('td', {class: 'num', title: 'fraction of the final policy\'s verdict rollouts held',
                    text: j.held_fraction === null || j.held_fraction === undefined ? '' : fixed(j.held_fraction, 2)}),
          lastErrorCell(j)))));
}

// The last error of a job that then completed belongs to an earlier attempt
// (a drain, a lost lease): shown muted, not as an alarm.
function lastErrorCell(j) {
  if (!j.last_error) return el('td', {});
  return j.state === 'completed'
      ? el('td', {class: 'muted', text: 'earlier attempt: ' + j.last_error})
      : el('td', {class: 'error', text: j.last_error});
}

async function renderSweep(view, name) {
  const q = encodeURIComponent(name);
  const [sweepData, curves, compare, jobs, finals, diagnostics] = await Promise.all([
    api('/api/sweep?name=' + q),
    api(`/api/curves?name=${q}&running=${state.includeRunning ? 1 : 0}`),
    api(`/api/compare?name=${q}&baseline=${encodeURIComponent(state.baseline)}`).catch(e => ({error: e.message})),
    api(`/api/jobs?name=${q}&limit=2000`),
    api('/api/final_trajectories?name=' + q).catch(e => ({error: e.message})),
    api(`/api/diagnostics?name=${q}&statistic=${encodeURIComponent(state.statistic)}`).catch(e => ({error: e.message})),
  ]);
  const s = sweepData.sweep;
  const running = el('input', {type: 'checkbox', id: 'include-running', checked: state.includeRunning,
                               onchange: e => { state.includeRunning = e.target.checked; refresh(); }});
  const baseline = el('select', {id: 'baseline', onchange: e => { state.baseline = e.target.value; refresh(); }},
      el('option', {value: '', text: 'every pair of methods'}),
      ...sweepData.table.methods.map(m => el('option', {value: m, text: 'each method vs ' + m,
                                                         selected: m === state.baseline})));
  view.replaceChildren(
      el('h2', {text: s.name}),
      el('p', {class: 'muted', text: s.description}),
      el('p', {id: 'sweep-progress'}, stateSpan(sweepState(s)), ' ', progressBar(s), ' ', jobCounts(s), '. ',
         el('span', {class: 'eta', title: s.eta.basis, text: 'Time to finish: ' + etaText(s)}),
         el('span', {class: 'muted', text: s.eta.known || s.finished ? '' : ` (${s.eta.basis})`})),
      el('h3', {text: 'Success rate [95% Wilson interval] n=trials, median final cost'}),
      table1(sweepData),
      sweepData.table.cells.length ? successChart(sweepData.table.variants.map(v => ({
          title: v || 'all trials',
          points: sweepData.table.cells.filter(c => c.variant === v).map(c => ({
              method: c.method, successes: c.successes, trials: c.trials, rate: c.success_rate,
              low: c.wilson95_low, high: c.wilson95_high, paper: null}))})),
          sweepData.table.colours) : null,
      el('p', {}, el('a', {id: 'table1-link', href: '#/table1/' + encodeURIComponent(s.name),
                           text: 'in the paper\'s Table 1 layout'})),
      el('h3', {text: 'Learning curves: evaluation cost per episode, median and quartiles over trials'}),
      el('div', {class: 'controls'}, el('label', {}, running, ' include the episodes of running trials'),
         el('span', {class: 'muted', text: `${curves.trials} trials in the curves`})),
      el('div', {id: 'curves'}, ...curves.panels.map(curvePanel)),
      el('h3', {text: 'Comparisons: paired by seed within each task variant'}),
      el('div', {class: 'controls'}, el('label', {}, 'compare ', baseline)),
      el('p', {class: 'muted', text: 'McNemar\'s exact test on per-seed success, Wilcoxon signed-rank test on ' +
          'per-seed final costs (cost shift = Hodges–Lehmann median difference, method − vs; negative: method lower), ' +
          'Fisher\'s exact test on all completed trials; two-sided, Holm-corrected over each variant\'s ' +
          'comparisons; power of each test at this n for the observed effect. Green: significant after Holm at α = ' +
          (compare.alpha || 0.05) + '; the verdict column names the test and the method it favours.'}),
      compare.error ? el('p', {class: 'error', text: compare.error}) : compareTable(compare),
      el('h3', {text: 'Estimator statistics per method: median and quartiles over completed trials'}),
      diagnostics.error ? el('p', {class: 'error', text: diagnostics.error}) : diagnosticsPanels(diagnostics),
      el('h3', {text: 'Final episodes of the completed trials'}),
      finals.error ? el('p', {class: 'error', text: finals.error}) : finalTrajectories(finals),
      el('h3', {text: `Jobs (${jobs.jobs.length}${jobs.next_after ? '+' : ''})`}),
      jobsTable(jobs.jobs));
  setCrumbs([['#/', 'sweeps'], [null, s.name]]);
}

function episodePlot(episodes) {
  const final = episodes.filter(e => e.eval_cost_mean !== null);
  if (!final.length) return null;
  const byAttempt = new Map();
  for (const e of final) {
    if (!byAttempt.has(e.attempt)) byAttempt.set(e.attempt, []);
    byAttempt.get(e.attempt).push(e);
  }
  const panel = {title: 'evaluation cost per episode (mean over evaluation rollouts)', variant: '',
                 threshold: null, methods: []};
  const colours = ['#1565c0', '#8d6e63', '#6a1b9a', '#00838f'];
  let i = 0;
  for (const [attempt, list] of byAttempt) {
    panel.methods.push({method: 'attempt ' + attempt, colour: colours[i++ % colours.length], trials: 1,
                        points: list.map(e => ({episode: e.episode, n: 1, q25: e.eval_cost_mean,
                                                median: e.eval_cost_mean, q75: e.eval_cost_mean}))});
  }
  return curvePanel(panel);
}

async function renderJob(view, id) {
  const data = await api('/api/job?id=' + encodeURIComponent(id));
  const j = data.job;
  const lastEpisode = Math.max(0, ...data.episodes.filter(e => e.final_attempt).map(e => e.episode));
  const trajectory = await trajectorySection(j.job_id, lastEpisode);
  const optionText = data.options.map(([k, v]) => `${k}=${v}`).join('\n');
  // replaceChildren turns a null child into the text "null": drop them.
  replacePresent(view,
      el('h2', {text: `Job ${j.job_id}: ${j.method}, seed ${j.seed}${j.variant ? ', ' + j.variant : ''}`}),
      el('p', {}, stateSpan(j.state), ` — ${j.episodes_stored}/${j.episodes_expected} episodes, ` +
         `${j.attempts} attempts, ${j.failures} failures, ${j.lost_leases} lost leases` +
         (j.state === 'completed' && j.final_eval_cost !== null ? `, final cost ${fixed(j.final_eval_cost, 3)} (${j.success ? 'success' : 'no success'})` : '') +
         (j.held_fraction !== null && j.held_fraction !== undefined ? `, rollouts held ${fixed(j.held_fraction, 2)} (${j.held_fraction >= 0.5 ? 'held' : 'not held'})` : '')),
      j.last_error ? el('p', {class: j.state === 'completed' ? 'muted' : 'error',
                              text: (j.state === 'completed' ? 'earlier attempt: ' : '') + j.last_error})
                   : null,
      el('details', {}, el('summary', {text: `options (${data.options.length})`}), el('pre', {text: optionText})),
      el('h3', {text: 'Episodes'}),
      episodePlot(data.episodes),
      el('h3', {text: 'Inside an episode: what happened against what the model predicted'}),
      trajectory,
      el('h3', {text: 'Estimator statistics per episode'}),
      statisticsPlots(data.episodes) || el('p', {class: 'muted', text: 'none recorded (PILCO, or a build before them)'}),
      el('table', {id: 'episodes'},
          el('thead', {}, el('tr', {}, ...['attempt', 'episode', 'real cost', 'eval mean', 'eval std',
                                            'predicted', 'work s', 'stored'].map(t => el('th', {text: t})))),
          el('tbody', {}, ...data.episodes.map(e => el('tr', {class: e.final_attempt ? null : 'muted'},
              el('td', {class: 'num', text: e.attempt}), el('td', {class: 'num', text: e.episode}),
              el('td', {class: 'num', text: fixed(e.real_cost, 3)}),
              el('td', {class: 'num', text: fixed(e.eval_cost_mean, 3)}),
              el('td', {class: 'num', text: fixed(e.eval_cost_std, 3)}),
              el('td', {class: 'num', text: fixed(e.predicted_cost, 3)}),
              el('td', {class: 'num', text: fixed(e.work_seconds, 2)}),
              el('td', {text: when(e.reported_ms)}))))),
      el('h3', {text: 'Attempts'}),
      el('table', {id: 'attempts'},
          el('thead', {}, el('tr', {}, ...['attempt', 'state', 'worker', 'host', 'started', 'ended', 'episodes',
                                            'error', 'build'].map(t => el('th', {text: t})))),
          el('tbody', {}, ...data.attempts.map(a => el('tr', {},
              el('td', {class: 'num', text: a.attempt}), el('td', {}, stateSpan(a.state)),
              el('td', {text: a.worker}), el('td', {text: a.host}), el('td', {text: when(a.started_ms)}),
              el('td', {text: when(a.ended_ms)}), el('td', {class: 'num', text: a.episodes_stored}),
              el('td', {class: 'error', text: a.error}), el('td', {class: 'muted', text: a.build}))))),
      el('h3', {text: 'Events'}),
      el('pre', {id: 'events', text: data.events.map(e =>
          `${when(e.ms)}  attempt ${e.attempt}  ${e.kind}  ${e.message}`).join('\n') || '(none)'}));
  setCrumbs([['#/', 'sweeps'], ['#/sweep/' + encodeURIComponent(data.sweep), data.sweep], [null, 'job ' + j.job_id]]);
}

// view.replaceChildren without the null and undefined children.
function replacePresent(view, ...children) {
  view.replaceChildren(...children.filter(child => child !== null && child !== undefined));
}

function setCrumbs(parts) {
  document.getElementById('crumbs').replaceChildren(...parts.map(([href, text]) =>
      href ? el('a', {href, text}) : el('span', {text})));
}

// ---- routing and refresh ----

async function refresh() {
  const generation = ++state.generation;
  clearTimeout(state.timer);
  const view = document.getElementById('view');
  const scratch = document.createElement('main');
  const route = location.hash.replace(/^#\/?/, '').split('/');
  try {
    if (route[0] === 'sweep' && route[1]) {
      await renderSweep(scratch, decodeURIComponent(route[1]));
    } else if (route[0] === 'job' && route[1]) {
      await renderJob(scratch, route[1]);
    } else if (route[0] === 'table1' && route[1]) {
      await renderTable1(scratch, route[1].split(',').filter(n => n).map(decodeURIComponent));
    } else {
      setCrumbs([]);
      await renderOverview(scratch);
    }
    if (generation !== state.generation) return;
    document.getElementById('login').hidden = true;
    // Keep the reader's place: swap the content, not the page.
    const scroll = window.scrollY;
    view.replaceChildren(...scratch.childNodes);
    window.scrollTo(0, scroll);
    document.getElementById('status').textContent = 'updated ' + new Date().toLocaleTimeString();
  } catch (error) {
    if (generation !== state.generation) return;
    if (error instanceof Unauthorized) {
      showLogin(error.message);
      return;  // no polling until a token is given
    }
    document.getElementById('status').textContent = 'error: ' + error.message;
    view.replaceChildren(el('p', {class: 'error', id: 'view-error', text: error.message}));
  }
  state.timer = setTimeout(() => { if (!document.hidden) refresh(); else state.timer = setTimeout(refresh, REFRESH_MS); },
                           REFRESH_MS);
}

document.addEventListener('DOMContentLoaded', () => {
  document.getElementById('login-form').addEventListener('submit', event => {
    event.preventDefault();
    sessionStorage.setItem(TOKEN_KEY, document.getElementById('token').value.trim());
    refresh();
  });
  window.addEventListener('hashchange', refresh);
  refresh();
});
