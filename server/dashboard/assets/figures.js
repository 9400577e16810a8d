// The paper's Table 1 grid and the success-rate figures of dashboard.js's
// sweep and Table-1 pages; the figures are the CLI's `results table --plot`
// and `results table1 --plot` (client/service_commands/success_plot.h).
// Uses el, svg and fixed of dashboard.js (loaded after this file; called
// only once both are).
'use strict';

// Success rates as a figure: one panel per task variant, each method a point
// at its rate with its 95% Wilson interval as a bar in the method's colour
// (the CLI's `results table --plot`), successes/trials above it, and the
// paper's rate as an open diamond where it has one. groups: [{title, points:
// [{method, successes, trials, rate, low, high, paper}]}], one method order.
function successChart(groups, colours) {
  const methods = [...new Set(groups.flatMap(g => g.points.map(p => p.method)))];
  const margin = {left: 44, right: 12, top: 34, bottom: 30};
  const plotW = Math.max(220, 54 * methods.length), plotH = 170;
  const width = margin.left + plotW + margin.right, height = margin.top + plotH + margin.bottom;
  const x = m => margin.left + (methods.indexOf(m) + 0.5) * plotW / methods.length;
  const y = v => margin.top + (1 - v) * plotH;
  return el('div', {id: 'success-chart', class: 'panels'}, ...groups.map(group => {
    const root = svg('svg', {class: 'panel success-panel', width, height, viewBox: `0 0 ${width} ${height}`,
                             'data-variant': group.title});
    root.append(svg('text', {class: 'title', x: margin.left, y: 14, text: group.title}));
    const axis = svg('g', {class: 'axis'});
    for (const t of [0, 0.2, 0.4, 0.6, 0.8, 1]) {
      axis.append(svg('line', {class: 'grid', x1: margin.left, x2: margin.left + plotW, y1: y(t), y2: y(t)}));
      axis.append(svg('text', {x: margin.left - 6, y: y(t) + 4, 'text-anchor': 'end', text: t}));
    }
    for (const m of methods) {
      axis.append(svg('text', {x: x(m), y: margin.top + plotH + 16, 'text-anchor': 'middle', text: m}));
    }
    axis.append(svg('rect', {x: margin.left, y: margin.top, width: plotW, height: plotH,
                             fill: 'none', stroke: '#90a4ae'}));
    root.append(axis);
    for (const p of group.points) {
      const cx = x(p.method), colour = colours[p.method] || '#455a64';
      root.append(svg('text', {class: 'count', x: cx, y: margin.top - 6, 'text-anchor': 'middle',
                               'data-method': p.method, text: `${p.successes}/${p.trials}`}));
      if (p.trials > 0) {
        const bar = svg('g', {class: 'rate', 'data-method': p.method},
            svg('title', {text: `${p.method}: ${fixed(p.rate, 2)} [${fixed(p.low, 2)}, ${fixed(p.high, 2)}], ` +
                                `${p.successes} of ${p.trials} trials`}));
        bar.append(svg('line', {x1: cx, x2: cx, y1: y(p.low), y2: y(p.high), stroke: colour, 'stroke-width': 2}));
        for (const v of [p.low, p.high]) {
          bar.append(svg('line', {x1: cx - 5, x2: cx + 5, y1: y(v), y2: y(v), stroke: colour, 'stroke-width': 2}));
        }
        bar.append(svg('circle', {cx, cy: y(p.rate), r: 4.5, fill: colour}));
        root.append(bar);
      }
      if (p.paper !== null && p.paper !== undefined) {
        const py = y(p.paper);
        root.append(svg('polygon', {class: 'paper', 'data-method': p.method, fill: 'none', stroke: '#000',
                                    'stroke-width': 1.3,
                                    points: `${cx},${py - 6} ${cx + 6},${py} ${cx},${py + 6} ${cx - 6},${py}`},
            svg('title', {text: `the paper: ${fixed(p.paper, 2)}`})));
      }
    }
    return root;
  }));
}

// The paper's Table 1 from several sweeps (/api/table1): one row per task
// (cost, k), one column per method; each cell our success rate with its
// Wilson interval and n, the rollout verdict's rate, and the paper's number,
// inside or outside our interval. '*' marks a cell whose trials left the
// paper's protocol; the list below the grid says which option differs.
function paperTable1(data) {
  const {methods, rows, cells} = data;
  const cellOf = (r, m) => cells[r * methods.length + m];
  const marked = [];
  const grid = el('table', {id: 'table1-grid'},
      el('thead', {}, el('tr', {}, el('th', {text: 'task'}), ...methods.map(m => el('th', {text: m})))),
      el('tbody', {}, ...rows.map((row, r) => el('tr', {'data-task': row.label}, el('th', {text: row.label}),
          ...methods.map((m, i) => {
            const c = cellOf(r, i);
            const off = c.off_protocol_trials > 0;
            if (off) marked.push(`${row.label}, ${m}: ${c.off_protocol_trials} of ${c.trials} trials: ${c.protocol_differences}`);
            const paper = c.paper_success_rate === null ? 'paper: none'
                : `paper ${fixed(c.paper_success_rate, 2)}` +
                  (c.paper_in_interval === 'yes' ? ' in' : c.paper_in_interval === 'no' ? ' OUT' : '');
            return el('td', {'data-method': m, class: off ? 'off-protocol' : null,
                             title: c.sweeps.length ? 'sweeps: ' + c.sweeps.join(', ') : null},
                el('div', {class: 'cell-rate', text: c.trials === 0 ? '–'
                    : `${fixed(c.success_rate, 2)} [${fixed(c.wilson95_low, 2)}, ${fixed(c.wilson95_high, 2)}] n=${c.trials}` +
                      (off ? '*' : '')}),
                c.classified > 0 ? el('div', {class: 'cell-sub cell-held',
                    text: `held ${c.held}/${c.classified} [${fixed(c.held_wilson95_low, 2)}, ${fixed(c.held_wilson95_high, 2)}]`}) : null,
                el('div', {class: 'cell-sub cell-paper' + (c.paper_in_interval === 'no' ? ' outside' : ''), text: paper}));
          })))));
  const protocol = data.protocol.map(([k, v]) => `${k} ${v}`).join(', ');
  // The figure: the tasks that have trials, every method in its place.
  const withTrials = rows.map((row, r) => ({row, r}))
      .filter(({r}) => methods.some((m, i) => cellOf(r, i).trials > 0));
  const chart = withTrials.length ? successChart(withTrials.map(({row, r}) => ({
      title: 'cart-pole swing-up, ' + row.label,
      points: methods.map((m, i) => {
        const c = cellOf(r, i);
        return {method: m, successes: c.successes, trials: c.trials, rate: c.success_rate,
                low: c.wilson95_low, high: c.wilson95_high, paper: c.paper_success_rate};
      })})), data.colours) : null;
  return [grid, chart,
          marked.length ? el('div', {id: 'table1-protocol'},
              el('p', {class: 'muted', text: `* not the paper's protocol (${protocol}):`}),
              el('ul', {}, ...marked.map(t => el('li', {text: t})))) : null,
          data.outside.length ? el('p', {class: 'muted', id: 'table1-outside',
                                         text: 'not in the grid: ' + data.outside.join('; ')}) : null];
}
