/* rasm report and dashboard: draws the model that rasm.report builds (see model.py, verdicts.py).
   RasmReport.render(model) draws (or redraws) every view; RasmReport.focus(t) moves the marker
   of every timeline to time t and zooms around it; RasmReport.live(url) follows a dashboard's
   server-sent events. Plotly (embedded in the page) draws the figures. */
(function () {
  "use strict";
  var STAGE_COLORS = {monitor: "#4c78a8", analyse: "#f58518", plan: "#54a24b",
                      legitimate: "#b279a2", execute: "#e45756"};
  var VERDICT_COLORS = {"true": "#59a14f", "false": "#e15759", "null": "#bab0ac",
                        "error": "#7b3294", "warm-up": "#f2c14e"};
  var VERDICT_NAMES = {"true": "holds", "false": "violated", "null": "inconclusive",
                       "error": "error (not evaluated)", "warm-up": "not judged yet"};
  var TIMELINES = ["gantt", "verdicts", "robustness", "signals"];
  var MAX_SIGNALS = 12;
  var MAX_ROWS = 500;
  var state = {model: null, focus: null, half: 2, iteration: null, drawn: {}};
  var CONFIG = {displaylogo: false, responsive: true};

  function $(id) { return document.getElementById(id); }
  function esc(text) {
    return String(text === null || text === undefined ? "" : text)
      .replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;").replace(/"/g, "&quot;");
  }
  function fmt(t) { return (t === null || t === undefined) ? "–" : Number(t).toFixed(3) + " s"; }
  function ms(seconds) { return seconds === null || seconds === undefined ? null : seconds * 1000; }
  function fmtMs(seconds) {
    var v = seconds * 1000;
    return v >= 100 ? v.toFixed(1) : v >= 1 ? v.toFixed(3) : v.toPrecision(3);
  }

  function missing(id, text) {
    var figure = $(id);
    if (state.drawn[id]) { Plotly.purge(figure); state.drawn[id] = false; }
    figure.classList.add("empty");
    figure.innerHTML = '<p class="missing">' + esc(text) + "</p>";
  }
  function draw(id, data, layout) {
    var figure = $(id);
    if (!state.drawn[id]) { figure.innerHTML = ""; figure.classList.remove("empty"); }
    layout.uirevision = "keep";
    layout.margin = layout.margin || {l: 70, r: 20, t: 30, b: 40};
    Plotly.react(figure, data, layout, CONFIG);
    state.drawn[id] = true;
  }

  function timeAxis() {
    return {title: {text: "time (s)"}, zeroline: false};
  }

  /* ------------------------------------------------------------------ header */
  function header(m) {
    $("source").textContent = m.source || "";
    var span = m.start === null ? "no records" :
      m.records + " records, " + fmt(m.start) + " – " + fmt(m.end);
    $("span").textContent = span;
    var c = m.counts || {};
    ["anomalies", "plans", "executed", "rejected", "dropped", "cancelled",
     "fallback"].forEach(function (k) {
      $("count-" + k).textContent = c[k] || 0;
    });
    $("status").textContent = !m.live ? "generated " + (m.generated || "") :
      m.status === "finished" ? "run finished" : m.status === "starting" ?
      "waiting for the loop to start" : "live: running";
    $("status").className = m.live && m.status !== "finished" ? "status running" : "status";
    var notes = $("notes");
    notes.innerHTML = (m.missing || []).map(function (n) { return "<li>" + esc(n) + "</li>"; })
      .join("");
    notes.hidden = !(m.missing && m.missing.length);
  }

  /* ------------------------------------------------------------------ live: modes and nodes */
  function modes(m) {
    var section = $("components");
    if (!m.live) { section.hidden = true; return; }
    section.hidden = false;
    var rows = Object.keys(m.modes || {}).map(function (name) {
      var mode = m.modes[name];
      return '<tr data-block="' + esc(name) + '"><td>' + esc(name) + '</td><td class="mode mode-' +
        esc(mode) + '">' + esc(mode) + "</td></tr>";
    });
    $("modes").innerHTML = rows.length ? rows.join("") :
      '<tr><td colspan="2" class="missing">no building block reported a mode yet</td></tr>';
    var nodes = m.nodes || {};
    var list = nodes.remote || [];
    $("nodes").innerHTML = list.length ? list.map(function (n) {
      return "<li>" + esc(n.name) + ": " + esc(n.state) + "</li>";
    }).join("") : '<li class="missing">' + esc(nodes.note || "no remote nodes") + "</li>";
  }

  /* ------------------------------------------------------------------ Gantt */
  function gantt(m) {
    var its = m.iterations || [];
    if (!its.length) {
      missing("gantt", "No MAPLE-K stage timing in this trace: no record has a 'stage' key " +
        "with its 'duration' (rasm run --trace writes them).");
      missing("gantt-detail", "No loop iteration to show.");
      return;
    }
    var data = m.stages.map(function (stage) {
      return {type: "bar", name: stage, marker: {color: STAGE_COLORS[stage]},
        x: its.map(function (it) { return it.time; }),
        y: its.map(function (it) { return ms(it.stages[stage]); }),
        hovertemplate: stage + " at %{x:.3f} s: %{y:.4f} ms<extra></extra>"};
    });
    var scale = state.focus === null ? ganttRange(m, -Infinity, Infinity) :
      ganttRange(m, state.focus - state.half, state.focus + state.half);
    ganttNote(scale.clipped);
    var yaxis = {title: {text: "stage duration (ms, stacked in loop order)"}};
    if (scale.range) yaxis.range = scale.range;
    draw("gantt", data, {barmode: "stack", bargap: 0.15, xaxis: timeAxis(), yaxis: yaxis,
      legend: {orientation: "h", y: 1.12, traceorder: "normal"}, shapes: markers(m, "gantt")});
    var figure = $("gantt");
    if (!figure._rasmClick) {
      figure.on("plotly_click", function (e) { if (e.points.length) focus(e.points[0].x); });
      figure._rasmClick = true;
    }
    detail(m);
  }

  function total(it) {
    var sum = 0;
    Object.keys(it.stages).forEach(function (s) { sum += it.stages[s] || 0; });
    return sum * 1000;
  }

  /* A y range for the iterations in [lo, hi]: one slow outlier must not flatten the others, so
     iterations over 3 × the 95th percentile are clipped (and named in the note). */
  function ganttRange(m, lo, hi) {
    var its = (m.iterations || []).filter(function (it) { return it.time >= lo && it.time <= hi; });
    var totals = its.map(total).sort(function (a, b) { return a - b; });
    if (!totals.length) return {range: null, clipped: []};
    var p95 = totals[Math.max(0, Math.ceil(0.95 * totals.length) - 1)];
    var top = totals[totals.length - 1];
    if (top <= 3 * p95 || p95 <= 0) return {range: [0, top * 1.08], clipped: []};
    var limit = p95 * 1.5;
    return {range: [0, limit], clipped: its.filter(function (it) { return total(it) > limit; })};
  }

  function ganttNote(clipped) {
    $("gantt-note").textContent = clipped.length ? "Scale clipped at the slow end: " +
      clipped.slice(0, 5).map(function (it) {
        return fmt(it.time) + " took " + total(it).toFixed(3) + " ms";
      }).join(", ") + (clipped.length > 5 ? ", … (" + clipped.length + " in all)" : "") + "." :
      "";
  }

  function iterationAt(m, t) {
    var its = m.iterations || [], found = null;
    for (var i = 0; i < its.length; i++) {
      if (t === null || its[i].time <= t + 1e-9) found = its[i]; else break;
    }
    return found || its[0];
  }

  function slowest(m) {
    var best = null, most = -1;
    (m.iterations || []).forEach(function (it) {
      var sum = total(it);
      if (sum > most) { most = sum; best = it; }
    });
    return best;
  }

  function detail(m) {
    var it = state.focus !== null ? iterationAt(m, state.focus) :
      (m.live ? m.iterations[m.iterations.length - 1] : slowest(m));
    if (!it) return;
    state.iteration = it.time;
    var offset = 0, data = [];
    m.stages.forEach(function (stage) {
      var d = it.stages[stage];
      if (d === undefined || d === null) return;
      data.push({type: "bar", orientation: "h", name: stage, showlegend: false,
        marker: {color: STAGE_COLORS[stage]}, y: [stage], base: [offset * 1000], x: [d * 1000],
        hovertemplate: stage + ": starts at %{base:.4f} ms, takes %{x:.4f} ms<extra></extra>"});
      offset += d;
    });
    $("detail-title").textContent = "iteration at " + fmt(it.time) + ": " + fmtMs(offset) +
      " ms in all" + (state.focus === null && !m.live ? " (the slowest; click a bar or an " +
      "adaptation to show another)" : "");
    draw("gantt-detail", data, {barmode: "overlay", xaxis: {title: {text: "ms from the start " +
      "of the iteration"}}, yaxis: {categoryorder: "array", categoryarray: m.stages.slice()
      .reverse()}, margin: {l: 90, r: 20, t: 10, b: 40}});
  }

  /* ------------------------------------------------------------------ stage durations */
  function timing(m) {
    var stages = m.stages.filter(function (s) { return m.durations && m.durations[s]; });
    if (!stages.length) {
      missing("timing", "No stage durations in this trace (no 'stage' records with 'duration').");
      $("timing-table").innerHTML = "";
      return;
    }
    var data = stages.map(function (stage) {
      return {type: "box", name: stage, y: m.durations[stage].map(ms), boxpoints: "outliers",
        marker: {color: STAGE_COLORS[stage]}, hovertemplate: "%{y:.4f} ms<extra>" + stage +
        "</extra>"};
    });
    draw("timing", data, {yaxis: {type: "log", title: {text: "duration (ms, log scale)"}},
      showlegend: false});
    var rows = stages.map(function (stage) {
      var t = m.timing[stage];
      return '<tr data-stage="' + stage + '"><td>' + stage + "</td><td>" + t.count + "</td>" +
        ["p50", "p90", "p99", "max", "mean"].map(function (q) {
          return "<td>" + fmtMs(t[q]) + "</td>";
        }).join("") + "</tr>";
    });
    $("timing-table").innerHTML = "<thead><tr><th>stage</th><th>runs</th><th>p50</th>" +
      "<th>p90</th><th>p99</th><th>max</th><th>mean</th></tr></thead><tbody>" + rows.join("") +
      "</tbody>";
  }

  /* ------------------------------------------------------------------ verdicts */
  function verdicts(m) {
    var props = (m.properties && m.properties.timelines) || [];
    var files = (m.properties && m.properties.files) || [];
    $("property-files").textContent = files.length ? "Properties from " + files.join(", ") + "." :
      "";
    if (!props.length) {
      missing("verdicts", (m.properties && m.properties.note) ||
        "No properties: verdict timelines need property files (rasm report TRACE --props FILE.rv).");
      $("verdict-table").innerHTML = "";
      $("violations").innerHTML = "";
      return;
    }
    var names = props.map(function (p) { return p.name; });
    var data = [];
    ["true", "false", "null", "error", "warm-up"].forEach(function (key) {
      var base = [], x = [], y = [];
      props.forEach(function (p) {
        p.runs.forEach(function (r) {
          if (String(r[2]) !== key) return;
          base.push(r[0]); x.push(Math.max(r[1] - r[0], 0)); y.push(p.name);
        });
      });
      if (!x.length) return;
      data.push({type: "bar", orientation: "h", name: VERDICT_NAMES[key], base: base, x: x, y: y,
        marker: {color: VERDICT_COLORS[key]}, width: 0.6,
        hovertemplate: "%{y}: " + VERDICT_NAMES[key] + " %{base:.3f}–%{customdata:.3f} s" +
          "<extra></extra>", customdata: base.map(function (b, i) { return b + x[i]; })});
    });
    var vx = [], vy = [], vt = [];
    props.forEach(function (p) {
      p.violations.forEach(function (v) {
        vx.push(v.time); vy.push(p.name);
        var episode = (p.episodes || []).filter(function (e) {
          return e.start <= v.time && v.time <= e.end && e.start !== v.time;
        })[0];
        vt.push((v.explanation || [episode ? "(in the episode from " + fmt(episode.start) + ")" :
          "(not explained)"]).join("<br>"));
      });
    });
    if (vx.length) {
      data.push({type: "scatter", mode: "markers", name: "violation", x: vx, y: vy, text: vt,
        marker: {symbol: "x-thin-open", size: 11, color: "#b00020", line: {width: 2}},
        hovertemplate: "%{y} violated at %{x:.3f} s<br>%{text}<extra></extra>"});
    }
    draw("verdicts", data, {barmode: "overlay", xaxis: timeAxis(),
      yaxis: {categoryorder: "array", categoryarray: names.slice().reverse(), automargin: true},
      height: Math.max(160, 36 * names.length + 90), legend: {orientation: "h", y: 1.15},
      shapes: markers(m, "verdicts"), margin: {l: 10, r: 20, t: 30, b: 40}});
    $("verdict-table").innerHTML = "<thead><tr><th>property</th><th>verdict</th>" +
      "<th>violations</th><th>errors</th><th>judged records</th><th>why</th><th>reads</th>" +
      "<th>defined at</th></tr></thead><tbody>" + props.map(function (p) {
        /* the state in words; only satisfied is green (a class name has no spaces) */
        var why = p.verdict === "satisfied" ? "" : (p.describe || "");
        return '<tr data-property="' + esc(p.name) + '"><td>' + esc(p.name) +
          '</td><td class="verdict-' + esc(String(p.verdict).replace(/ /g, "-")) + '">' +
          esc(p.word || p.verdict) + "</td><td>" + p.violated +
          (p.episodes && p.episodes.length && p.episodes.length < p.violated ? " (" +
            p.episodes.length + " episode" + (p.episodes.length === 1 ? "" : "s") + ")" : "") +
          "</td><td>" + p.errors +
          "</td><td>" + p.judged + "</td><td>" + esc(why) + "</td><td>" +
          esc(p.reads.join(", ")) + "</td><td>" + esc(p.source) + "</td></tr>";
      }).join("") + "</tbody>";
    var items = [];
    props.forEach(function (p) {
      /* consecutive violations are one episode: its span, its records, its first explained */
      var episodes = p.episodes || [];
      episodes.slice(0, 20).forEach(function (e) {
        var records = e.first === null || e.first === undefined ? "" : e.count === 1 ?
          " at record " + e.first : " at records " + e.first + "–" + e.last;
        var span = e.until === null ?
          " from " + fmt(e.start) + " to the end of the trace (" + fmt(e.end) + ")" :
          " for " + fmt(e.until - e.start);
        items.push('<li class="episode">' + goto(e.start) + " <b>" + esc(p.name) +
          "</b> violated" + span + " (" + e.count + " record" + (e.count === 1 ? "" : "s") +
          records + ")" +
          (e.explanation ? "<pre>" + esc(e.explanation.join("\n")) + "</pre>" : "") + "</li>");
      });
      if (episodes.length > 20) {
        items.push("<li>… " + (episodes.length - 20) + " more episodes of " + esc(p.name) +
          "</li>");
      }
    });
    $("violations").innerHTML = items.join("");
  }

  /* ------------------------------------------------------------------ robustness */
  function robustness(m) {
    /* Each property's robustness (SPEC §12) as the Trustworthiness Checker wrote it: how far
       from a violation, 0 the boundary. ±inf ("inf" in the model: decided by booleans alone)
       breaks the line; a property that never had a finite value is named, not drawn. */
    var all = m.robustness || {}, drawn = [], infinite = [];
    Object.keys(all).sort().forEach(function (name) {
      var s = all[name];
      var y = s.v.map(function (v) { return typeof v === "number" ? v : null; });
      if (y.some(function (v) { return v !== null; })) {
        drawn.push({type: "scatter", mode: "lines", line: {shape: "hv", width: 1.5}, x: s.t,
          y: y, name: name, connectgaps: false,
          hovertemplate: name + " robustness %{y:.4g} at %{x:.3f} s<extra></extra>"});
      } else {
        infinite.push(name);
      }
    });
    $("robustness-note").textContent = (drawn.length ? "How far each property is from a " +
      "violation (its robustness, written by the Trustworthiness Checker): above 0 it holds. " +
      "A gap is an infinite value (decided by booleans alone)." : "") +
      (infinite.length ? " Only ±∞ (boolean): " + infinite.join(", ") + "." : "");
    if (!drawn.length) {
      missing("robustness", "No robustness in this trace: its records carry no " +
        "robustness_<property> values (a trace that rasm run writes has them).");
      return;
    }
    draw("robustness", drawn, {xaxis: timeAxis(), yaxis: {title: {text: "robustness"},
      zeroline: false}, height: 280, shapes: markers(m, "robustness"),
      legend: {orientation: "h"}});
  }

  /* ------------------------------------------------------------------ signals */
  function signals(m) {
    var all = m.signals || {};
    var read = {};
    ((m.properties && m.properties.timelines) || []).forEach(function (p) {
      p.reads.forEach(function (r) { read[r] = true; });
    });
    var names = Object.keys(all).sort(function (a, b) {
      return (read[b] ? 1 : 0) - (read[a] ? 1 : 0) || a.localeCompare(b);
    });
    var shown = names.slice(0, MAX_SIGNALS);
    $("signals-note").textContent = names.length > MAX_SIGNALS ? "Showing " + MAX_SIGNALS +
      " of " + names.length + " signals (those the properties read first); not shown: " +
      names.slice(MAX_SIGNALS).join(", ") + "." : names.length ? "Signals the properties read " +
      "are marked ●; dashed lines mark adaptations." : "";
    if (!shown.length) {
      missing("signals", "No knowledge signals in this trace: its records carry only the loop's " +
        "own keys (stage, events, plans).");
      return;
    }
    var n = shown.length, gap = 0.04, h = (1 - gap * (n - 1)) / n;
    var layout = {xaxis: timeAxis(), showlegend: false, height: Math.max(220, 110 * n + 60),
      margin: {l: 130, r: 20, t: 10, b: 40}, shapes: markers(m, "signals")};
    var data = shown.map(function (name, i) {
      var s = all[name], axis = i === 0 ? "y" : "y" + (i + 1);
      var key = i === 0 ? "yaxis" : "yaxis" + (i + 1);
      var top = 1 - i * (h + gap);
      var y = s.kind === "bool" ? s.v.map(function (v) { return v ? 1 : 0; }) : s.v;
      layout[key] = {domain: [Math.max(top - h, 0), top], title: {text: (read[name] ? "● " : "") +
        name, font: {size: 11}}, automargin: true};
      if (s.kind === "bool") {
        layout[key].tickvals = [0, 1]; layout[key].ticktext = ["false", "true"];
        layout[key].range = [-0.2, 1.2];
      }
      if (s.kind === "str") layout[key].type = "category";
      return {type: "scatter", mode: "lines", line: {shape: "hv", width: 1.5}, x: s.t, y: y,
        name: name, yaxis: axis, hovertemplate: name + " = %{y} at %{x:.3f} s<extra></extra>"};
    });
    data.forEach(function (d) { d.xaxis = "x"; });
    layout.xaxis.anchor = n === 1 ? "y" : "y" + n;  /* the time axis under the lowest signal */
    draw("signals", data, layout);
  }

  /* ------------------------------------------------------------------ adaptations */
  function goto(t) {
    return '<a class="goto" href="#t=' + t + '" data-time="' + t + '">' + fmt(t) + "</a>";
  }

  function adaptations(m) {
    var list = m.adaptations || [];
    if (!list.length) {
      $("adaptations-missing").hidden = false;
      $("adaptations-missing").textContent = "No adaptations in this trace: no record has " +
        "'anomaly' or 'planned' (the loop never found an anomaly, or the trace is not a loop's).";
      $("adaptations").querySelector("tbody").innerHTML = "";
      return;
    }
    $("adaptations-missing").hidden = true;
    var shown = list.slice(-MAX_ROWS);
    $("adaptations").querySelector("tbody").innerHTML = shown.map(function (a) {
      var params = Object.keys(a.params || {}).map(function (k) {
        return esc(k) + "=" + esc(a.params[k]);
      }).join(", ");
      var legit = a.legitimacy === "rejected" ? '<span class="bad">rejected</span>' +
        (a.broken_rules.length ? "<br>broken: " + esc(a.broken_rules.join(", ")) : "") :
        a.legitimacy === "accepted" ? '<span class="good">accepted</span>' : "–";
      var outcome = a.outcome || (m.live && m.status !== "finished" ? "in progress" : "–");
      var cls = {executed: "good", rejected: "bad", dropped: "bad", cancelled: "bad",
        "no plan": "bad", "stage failed": "bad"}[outcome] || "";
      var why = [a.plan_explanation, a.legitimacy_explanation].concat(a.notes || [])
        .filter(function (x) { return x; }).map(esc).join("<br>");
      return '<tr id="adaptation-' + a.number + '" data-time="' + a.time + '"><td>' + a.number +
        "</td><td>" + goto(a.time) + "</td><td>" + esc(a.anomaly || "(no anomaly record)") +
        "</td><td>" + (a.plan ? "<b>" + esc(a.plan) + "</b> " + params : "–") + "</td><td>" +
        legit + "</td><td>" + (a.trusted ? '<span class="good">registered</span>' : "–") +
        '</td><td class="outcome ' + cls + '">' + esc(outcome) + "</td><td>" + why + "</td></tr>";
    }).join("");
    if (state.focus !== null) highlight(state.focus);
  }

  /* ------------------------------------------------------------------ fallback */
  function fallback(m) {
    var list = m.fallback || [];
    $("fallback").hidden = !list.length;
    $("fallback-table").querySelector("tbody").innerHTML = list.slice(-MAX_ROWS).map(function (f) {
      var actions = f.actions.map(function (a) {
        return goto(a.time) + ' <span class="' + (a.outcome === "executed" ? "good" : "bad") +
          '">' + esc(a.outcome === "executed" ? "sent" : "dropped") + "</span> " +
          esc(a.explanation || "");
      }).join("<br>") || "–";
      var released = f.released === null ? (m.live && m.status !== "finished" ?
        "still engaged" : "still engaged at the end") :
        goto(f.released) + " " + esc(f.release || "");
      var end = f.released === null ? m.end : f.released;
      return '<tr data-time="' + f.engaged + '"><td>' + goto(f.engaged) + "</td><td>" +
        esc(f.reason || "") + "</td><td>" + actions + "</td><td>" + released + "</td><td>" +
        fmt(end - f.engaged) + (f.released === null ? " so far" : "") + "</td></tr>";
    }).join("");
  }

  /* ------------------------------------------------------------------ managed-system modes */
  function modeChanges(m) {
    var list = m.mode_changes || [];
    $("mode-changes").hidden = !list.length;
    $("mode-table").querySelector("tbody").innerHTML = list.slice(-MAX_ROWS).map(function (c) {
      return '<tr data-time="' + c.time + '"><td>' + goto(c.time) + "</td><td>" +
        esc(c.mode) + "</td></tr>";
    }).join("");
  }

  /* ------------------------------------------------------------------ focus */
  function markers(m, id) {
    var shapes = [];
    if (id === "signals" || id === "verdicts" || id === "robustness") {
      (m.fallback || []).forEach(function (f) {  /* the fallback's episodes, shaded */
        shapes.push({type: "rect", xref: "x", yref: "paper", x0: f.engaged,
          x1: f.released === null ? m.end : f.released, y0: 0, y1: 1, layer: "below",
          fillcolor: "rgba(242, 142, 43, 0.12)", line: {width: 0}});
      });
    }
    if (id === "robustness") {  /* the boundary: below it, the property is violated */
      shapes.push({type: "line", xref: "paper", yref: "y", x0: 0, x1: 1, y0: 0, y1: 0,
        line: {color: "#e15759", width: 1, dash: "dash"}});
    }
    if (id === "signals") {
      (m.adaptations || []).forEach(function (a) {
        if (a.outcome !== "executed" && a.outcome !== "rejected") return;
        shapes.push({type: "line", xref: "x", yref: "paper", x0: a.time, x1: a.time, y0: 0,
          y1: 1, line: {color: a.outcome === "executed" ? "#f28e2b" : "#e15759", width: 1,
          dash: "dot"}});
      });
    }
    if (state.focus !== null) {
      shapes.push({type: "line", name: "focus", xref: "x", yref: "paper", x0: state.focus,
        x1: state.focus, y0: 0, y1: 1, line: {color: "#111", width: 2}});
    }
    return shapes;
  }

  function highlight(t) {
    var rows = document.querySelectorAll("#adaptations tbody tr");
    rows.forEach(function (row) {
      row.classList.toggle("selected", Math.abs(Number(row.dataset.time) - t) < 1e-9);
    });
  }

  function focus(t) {
    var m = state.model;
    t = Number(t);
    state.focus = t;
    document.body.dataset.focus = String(t);
    if (!m) return;
    var span = (m.end - m.start) || 1;
    var half = Math.max(span * 0.05, 2);
    state.half = half;
    TIMELINES.forEach(function (id) {
      if (!state.drawn[id]) return;
      var update = {"xaxis.range": [t - half, t + half], shapes: markers(m, id)};
      if (id === "gantt") {
        var scale = ganttRange(m, t - half, t + half);
        if (scale.range) update["yaxis.range"] = scale.range;
        ganttNote(scale.clipped);
      }
      Plotly.relayout($(id), update);
    });
    if (m.iterations && m.iterations.length) detail(m);
    highlight(t);
    $("focus-note").textContent = "Timelines zoomed to " + fmt(t - half) + " – " +
      fmt(t + half) + " around " + fmt(t) + ".";
    $("focus-reset").hidden = false;
  }

  function reset() {
    state.focus = null;
    delete document.body.dataset.focus;
    TIMELINES.forEach(function (id) {
      if (!state.drawn[id]) return;
      var update = {"xaxis.autorange": true, shapes: markers(state.model, id)};
      if (id === "gantt") {
        var scale = ganttRange(state.model, -Infinity, Infinity);
        if (scale.range) update["yaxis.range"] = scale.range;
        ganttNote(scale.clipped);
      }
      Plotly.relayout($(id), update);
    });
    highlight(NaN);
    $("focus-note").textContent = "";
    $("focus-reset").hidden = true;
    if (state.model.iterations && state.model.iterations.length) detail(state.model);
  }

  document.addEventListener("click", function (e) {
    var link = e.target.closest && e.target.closest("a.goto");
    if (!link) return;
    e.preventDefault();
    history.replaceState(null, "", "#t=" + link.dataset.time);
    focus(link.dataset.time);
    $("timelines").scrollIntoView({block: "start"});
  });

  function fromHash() {
    var match = /^#t=([-0-9.eE+]+)$/.exec(location.hash);
    if (match) focus(match[1]);
  }

  /* ------------------------------------------------------------------ entry points */
  function render(m) {
    state.model = m;
    header(m);
    modes(m);
    gantt(m);
    timing(m);
    verdicts(m);
    robustness(m);
    signals(m);
    adaptations(m);
    fallback(m);
    modeChanges(m);
    document.body.dataset.records = String(m.records);
    document.body.dataset.rendered = "true";
  }

  function live(url) {
    /* A render takes a while with big figures: draw only the newest model, never a backlog. */
    var source = new EventSource(url), latest = null, scheduled = false;
    function flush() {
      scheduled = false;
      if (latest === null) return;
      var m = JSON.parse(latest);
      latest = null;
      render(m);
      if (m.status === "finished") source.close();
    }
    source.onmessage = function (e) {
      latest = e.data;
      if (!scheduled) { scheduled = true; setTimeout(flush, 0); }
    };
    source.onerror = function () {
      if (state.model && state.model.status === "finished") return;
      $("status").textContent = "disconnected (the run ended or the server stopped)";
      $("status").className = "status";
      source.close();
    };
  }

  window.RasmReport = {render: render, focus: focus, reset: reset, live: live};
  document.addEventListener("DOMContentLoaded", function () {
    $("focus-reset").addEventListener("click", reset);
    var data = $("rasm-data");
    if (data) {
      render(JSON.parse(data.textContent));
      fromHash();
    }
    window.addEventListener("hashchange", fromHash);
    var body = document.body;
    if (body.dataset.events) live(body.dataset.events);
  });
})();
