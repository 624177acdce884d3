//! `replay.html`: the flight as one self-contained page that opens from disk (no server, no
//! network) — the scene's obstacles in 3D (moving ones animated), start and goal, the planned
//! path, the reference track, the flown track coloured by speed, the vehicle with its hull at
//! its attitude, the filter's region and interventions, the barriers it enforced, the obstacle
//! points it was given and the range sensors' returns at the shown time, the guidance- and
//! flight-mode changes and the events (failsafes, collision, end; [`overlays`]); play/pause,
//! a time slider, speed ×0.25–×16, follow camera or free orbit, and plots of speed, clearance
//! and h̄ with a cursor linked to the slider.
//!
//! The page embeds three.js r160 (MIT, `host-sim/assets/three/`, see its README), the page's
//! script (`app.js`, style `style.css`) and the data as JSON. The samples are **decimated for
//! display** ([`display_indices`]: at most [`MAX_DISPLAY_SAMPLES`], the last and the
//! minimum-clearance / minimum-h̄ samples always kept); every number the page shows as text is
//! the report's own text: a displayed sample's `t`, `x`, `y`, `z`, `clearance`, `h_bar` are the
//! digits of its `trajectory.csv` row (`crate::decimal`, the same writer), and the
//! `summary.json` table holds each value as serde_json writes it there. Mode changes, events
//! and filter-intervention intervals are taken from **every** sample (bounded by
//! [`MAX_MARKS`]); the filter's points and the returns are decimated as [`overlays`] says.
//!
//! Opened with `#t=SECONDS` (optionally `&cam=orbit`) the page jumps there, renders once and
//! writes a probe (`<pre id="probe">` JSON: obstacle meshes in the scene graph, the vehicle's
//! world and screen position, the texts shown, errors caught) for the headless-browser test
//! `host-sim/tests/replay_page.rs`.
//!
//! A run without samples still gets a valid page (the scene, and a banner saying there is
//! nothing to replay).
//!
//! Owns the page only; the records it shows are [`super::RunRecord`]'s.
//! May import: what [`super`] may ([`crate::world`], serde_json, [`crate::decimal`]).

use std::path::Path;

use parapet_core::obstacle::Shape;

use super::{RunRecord, Sample};
use crate::decimal::push_fixed;
use crate::world::scene::{ned_to_enu_arr, reference_point, to_f64, Motion, SceneObstacle};

/// The page's file name in a report directory.
pub const REPLAY_HTML: &str = "replay.html";

/// At most this many samples are drawn and animated (decimated evenly, see [`display_indices`]).
pub const MAX_DISPLAY_SAMPLES: usize = 3000;

/// At most this many mode changes and as many filter-intervention intervals are listed (the
/// page says when a list was cut).
pub const MAX_MARKS: usize = 2000;

/// three.js r160, `build/three.module.min.js` as published (see `host-sim/assets/three/README.md`).
const THREE_MODULE: &str = include_str!("../../../assets/three/three.module.min.js");
/// The page's script.
const APP_JS: &str = include_str!("app.js");
/// The page's style.
const STYLE_CSS: &str = include_str!("style.css");

/// The region names in the order of the page's `g` column (indices: `Region::code`).
const REGIONS: [&str; 5] = parapet_core::cbf::Region::NAMES;

/// Write `replay.html` for `rec` to `path`.
pub(super) fn write_replay(path: &Path, rec: &RunRecord) -> std::io::Result<()> {
    let page = page(rec).map_err(std::io::Error::other)?;
    std::fs::write(path, page)
}

/// The whole page text.
pub fn page(rec: &RunRecord) -> Result<String, String> {
    let three = wrap_three(THREE_MODULE)?;
    let data = data_json(rec);
    let title = html_escape(&format!("Parapet replay — {}", rec.summary.scene));
    let mut out = String::with_capacity(three.len() + data.len() + APP_JS.len() + STYLE_CSS.len() + 4096);
    out.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n");
    out.push_str("<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n");
    out.push_str(&format!("<title>{title}</title>\n"));
    // First of all: catch every error (the probe reports them).
    out.push_str(ERROR_CATCHER);
    out.push_str("<style>\n");
    out.push_str(STYLE_CSS);
    out.push_str("</style>\n</head>\n<body>\n");
    out.push_str(BODY);
    out.push_str("<script id=\"data\" type=\"application/json\">");
    out.push_str(&data);
    out.push_str("</script>\n<script>\n\"use strict\";\n");
    out.push_str(
        "// three.js r160 (https://threejs.org), MIT licence, Copyright 2010-2023 three.js authors;\n",
    );
    out.push_str("// build/three.module.min.js with its export statement turned into a return.\n");
    out.push_str("var THREE = (function () {\n\"use strict\";\n");
    out.push_str(&three);
    out.push_str("\n})();\n</script>\n<script>\n");
    out.push_str(APP_JS);
    out.push_str("</script>\n</body>\n</html>\n");
    Ok(out)
}

const ERROR_CATCHER: &str = "<script>\nwindow.__errors = [];\n\
window.addEventListener('error', function (e) { window.__errors.push(String(e.message || e.type) + (e.filename ? ' (' + e.filename + ':' + e.lineno + ')' : '')); });\n\
window.addEventListener('unhandledrejection', function (e) { window.__errors.push('unhandled rejection: ' + String(e.reason)); });\n\
(function () { var ce = console.error; console.error = function () { window.__errors.push(Array.prototype.map.call(arguments, String).join(' ')); return ce.apply(console, arguments); }; })();\n\
</script>\n";

const BODY: &str = r#"<div id="top">
 <button id="play" title="play / pause (space)">▶</button>
 <input id="slider" type="range" min="0" max="0" value="0" step="1" aria-label="time">
 <span class="lbl">t = <b id="t-val">-</b> s</span>
 <label>speed <select id="rate"><option>0.25</option><option>0.5</option><option selected>1</option><option>2</option><option>4</option><option>8</option><option>16</option></select>×</label>
 <label>camera <select id="cam"><option value="follow" selected>follow</option><option value="orbit">free orbit</option></select></label>
 <span id="title"></span>
</div>
<div id="main">
 <div id="viewwrap"><canvas id="view"></canvas><div id="banner" hidden></div><div id="legend"></div></div>
 <div id="side">
  <table id="now"></table>
  <details open><summary>Events</summary><div id="events"></div></details>
  <details open><summary>Mode changes</summary><div id="modes"></div></details>
  <details><summary>Barriers enforced (filter interventions)</summary><div id="barriers"></div></details>
  <details><summary>summary.json</summary><table id="summary"></table></details>
  <p class="note" id="note"></p>
 </div>
</div>
<div id="plots"><canvas id="plot-speed"></canvas><canvas id="plot-clearance"></canvas><canvas id="plot-hbar"></canvas></div>
<pre id="probe" hidden></pre>
"#;

/// The module text of three.js as a function body: its one `export{a as B,…};` statement
/// becomes `return{B:a,…};`. Checked by `three_is_wrapped`.
fn wrap_three(src: &str) -> Result<String, String> {
    let at = src.rfind("export{").ok_or("three.js: no export statement")?;
    let rest = &src[at + "export{".len()..];
    let end = rest.find('}').ok_or("three.js: unterminated export statement")?;
    let mut out = String::with_capacity(src.len());
    out.push_str(&src[..at]);
    out.push_str("return{");
    for (i, item) in rest[..end].split(',').enumerate() {
        let item = item.trim();
        let (local, exported) = match item.split_once(" as ") {
            Some((l, e)) => (l.trim(), e.trim()),
            None => (item, item),
        };
        if local.is_empty() || exported.is_empty() {
            return Err(format!("three.js: export item {i} `{item}` not understood"));
        }
        if i > 0 {
            out.push(',');
        }
        out.push_str(exported);
        out.push(':');
        out.push_str(local);
    }
    out.push('}');
    out.push_str(&rest[end + 1..]);
    if out.contains("</script") {
        return Err("three.js: contains </script".into());
    }
    Ok(out)
}

fn html_escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// The indices of the samples the page draws: evenly spaced (every `ceil(n / max)`-th), plus
/// the last sample and those of minimum clearance and minimum h̄ (so the worst moment is
/// always shown); sorted, at most `max + 3`.
pub fn display_indices(samples: &[Sample], max: usize) -> Vec<usize> {
    let n = samples.len();
    if n == 0 {
        return Vec::new();
    }
    let stride = n.div_ceil(max.max(1));
    let mut v: Vec<usize> = (0..n).step_by(stride).collect();
    v.push(n - 1);
    let argmin = |f: &dyn Fn(&Sample) -> f64| {
        samples
            .iter()
            .enumerate()
            .filter(|(_, s)| f(s).is_finite())
            .min_by(|a, b| f(a.1).total_cmp(&f(b.1)))
            .map(|(i, _)| i)
    };
    v.extend(argmin(&|s| s.clearance));
    v.extend(argmin(&|s| s.h_bar));
    v.sort_unstable();
    v.dedup();
    v
}

/// JSON text of the page's data, written by hand so that each number has the digits of the
/// report's files. Only strings can hold `<`, and they are written with it escaped, so the
/// text cannot end the `<script>` element it sits in.
fn data_json(rec: &RunRecord) -> String {
    let samples = rec.samples;
    let idx = display_indices(samples, MAX_DISPLAY_SAMPLES);
    let mut j = Json(Vec::with_capacity(64 * 1024 + idx.len() * 120));
    j.raw("{\"scene\":");
    j.string(&rec.summary.scene);
    j.raw(",\"scene_file\":");
    j.string(&rec.summary.scene_file);
    j.raw(",\"filter\":");
    j.string(&rec.summary.filter);
    j.raw(",\"end_reason\":");
    j.string(&rec.summary.end_reason);
    let (mn, mx) = rec.scene.bounds_enu;
    j.raw(",\"bounds\":[");
    j.arr(&mn, 4);
    j.raw(",");
    j.arr(&mx, 4);
    j.raw("],\"start\":");
    j.arr(&ned_to_enu_arr(&rec.scene.start), 4);
    j.raw(",\"goal\":");
    j.arr(&ned_to_enu_arr(&rec.scene.goal), 4);
    j.raw(",\"hull\":");
    j.num(rec.scene.vehicle.hull_radius, 4);
    j.raw(",\"arm\":");
    j.num(rec.scene.vehicle.arm_length, 4);
    // With range sensors the ids are perception tracks, not scene indices.
    let act_is_index = rec.range_sensors.is_empty() && rec.scene.obstacles.len() <= 65_535;
    j.raw(if act_is_index { ",\"act_is_index\":true" } else { ",\"act_is_index\":false" });
    j.raw(",\"path\":[");
    for (i, p) in rec.path.iter().enumerate() {
        j.sep(i);
        j.arr(&ned_to_enu_arr(p), 4);
    }
    j.raw("],\"obstacles\":[");
    for (i, o) in rec.scene.obstacles.iter().enumerate() {
        j.sep(i);
        obstacle_json(&mut j, o);
    }
    j.raw("],\"regions\":[");
    for (i, r) in REGIONS.iter().enumerate() {
        j.sep(i);
        j.string(r);
    }
    // Mode names, in order of first use.
    let mut modes: Vec<&'static str> = Vec::new();
    let mut mode_of = |m: &'static str| match modes.iter().position(|&x| x == m) {
        Some(i) => i,
        None => {
            modes.push(m);
            modes.len() - 1
        }
    };
    let mut changes: Vec<(f64, usize)> = Vec::new();
    let mut changes_cut = false;
    let mut last_mode = None;
    for s in samples {
        if last_mode != Some(s.mode) {
            last_mode = Some(s.mode);
            let m = mode_of(s.mode.as_str());
            if changes.len() < MAX_MARKS {
                changes.push((s.t, m));
            } else {
                changes_cut = true;
            }
        }
    }
    let sample_modes: Vec<usize> = idx.iter().map(|&i| mode_of(samples[i].mode.as_str())).collect();
    j.raw("],\"modes\":[");
    for (i, m) in modes.iter().enumerate() {
        j.sep(i);
        j.string(m);
    }
    j.raw("],\"mode_changes\":[");
    for (i, (t, m)) in changes.iter().enumerate() {
        j.sep(i);
        j.raw("[");
        j.num(*t, 4);
        j.raw(&format!(",{m}]"));
    }
    j.raw(if changes_cut { "],\"mode_changes_cut\":true" } else { "],\"mode_changes_cut\":false" });
    // Filter interventions over every sample, flight modes, events, range returns.
    overlays::interventions_json(&mut j, samples);
    overlays::flight_modes_json(&mut j, samples);
    overlays::events_json(&mut j, rec);
    overlays::scans_json(&mut j, rec);
    overlays::filter_points_json(&mut j, rec);
    j.raw(&format!(",\"n_samples\":{},\"n_display\":{}", samples.len(), idx.len()));
    j.raw(",\"collision_t\":");
    match rec.summary.first_collision_time_s {
        Some(t) => j.num(t, 4),
        None => j.raw("null"),
    }
    // The displayed samples, one array per column.
    let col = |j: &mut Json, name: &str, d: usize, f: &dyn Fn(&Sample) -> f64| {
        j.raw(&format!(",\"{name}\":["));
        for (n, &i) in idx.iter().enumerate() {
            j.sep(n);
            j.num(f(&samples[i]), d);
        }
        j.raw("]");
    };
    j.raw(",\"s\":{\"i\":[");
    for (n, &i) in idx.iter().enumerate() {
        j.sep(n);
        j.raw(&i.to_string());
    }
    j.raw("]");
    // As trajectory.csv writes them (its TrajectoryRow: ENU, 4 / 5 decimals).
    col(&mut j, "t", 4, &|s| s.t);
    col(&mut j, "x", 4, &|s| ned_to_enu_arr(&s.pos)[0]);
    col(&mut j, "y", 4, &|s| ned_to_enu_arr(&s.pos)[1]);
    col(&mut j, "z", 4, &|s| ned_to_enu_arr(&s.pos)[2]);
    col(&mut j, "c", 4, &|s| s.clearance);
    col(&mut j, "h", 5, &|s| s.h_bar);
    // Drawn only (never shown as text): reference, attitude, speed.
    col(&mut j, "rx", 3, &|s| ned_to_enu_arr(&s.ref_pos)[0]);
    col(&mut j, "ry", 3, &|s| ned_to_enu_arr(&s.ref_pos)[1]);
    col(&mut j, "rz", 3, &|s| ned_to_enu_arr(&s.ref_pos)[2]);
    col(&mut j, "roll", 4, &|s| s.rpy[0]);
    col(&mut j, "pitch", 4, &|s| s.rpy[1]);
    col(&mut j, "yaw", 4, &|s| s.rpy[2]);
    col(&mut j, "v", 3, &|s| s.vel.norm());
    let small = |j: &mut Json, name: &str, f: &dyn Fn(usize, &Sample) -> String| {
        j.raw(&format!(",\"{name}\":["));
        for (n, &i) in idx.iter().enumerate() {
            j.sep(n);
            j.raw(&f(n, &samples[i]));
        }
        j.raw("]");
    };
    small(&mut j, "g", &|_, s| s.filter.region.code().to_string());
    small(&mut j, "f", &|_, s| u8::from(s.filter.intervened).to_string());
    small(&mut j, "a", &|_, s| s.filter.active_id.map_or("-1".into(), |a| a.to_string()));
    small(&mut j, "m", &|n, _| sample_modes.get(n).copied().unwrap_or(0).to_string());
    small(&mut j, "n", &|_, s| s.filter.n_constraints.to_string());
    small(&mut j, "fm", &|_, s| (s.flight_mode as usize).to_string());
    j.raw("},\"summary\":[");
    summary_pairs(&mut j, rec.summary);
    j.raw("]}");
    // Only ASCII digits, punctuation and serde_json's (valid UTF-8) strings went in.
    String::from_utf8(j.0).unwrap_or_default()
}

/// One obstacle: kind and sizes as the scene schema has them, in ENU (file frame), its
/// reference point `r` (what waypoints move) and its motion.
fn obstacle_json(j: &mut Json, o: &SceneObstacle) {
    let (name, shape, motion) = (&o.name, &o.shape, &o.motion);
    let enu = |a: &[f32; 3]| ned_to_enu_arr(&to_f64(&(*a).into()));
    j.raw("{\"kind\":");
    match shape {
        Shape::Point { center } => {
            j.string("point");
            j.raw(",\"center\":");
            j.arr_f32(&enu(center));
        }
        Shape::Sphere { center, radius } => {
            j.string("sphere");
            j.raw(",\"center\":");
            j.arr_f32(&enu(center));
            j.raw(",\"radius\":");
            j.f32(*radius);
        }
        Shape::Box { min, max } => {
            let (a, b) = (enu(min), enu(max));
            j.string("box");
            j.raw(",\"min\":");
            j.arr_f32(&[a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])]);
            j.raw(",\"max\":");
            j.arr_f32(&[a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])]);
        }
        Shape::Cylinder { base, radius, height } => {
            j.string("cylinder");
            j.raw(",\"base\":");
            j.arr_f32(&enu(base));
            j.raw(",\"radius\":");
            j.f32(*radius);
            j.raw(",\"height\":");
            j.f32(*height);
        }
    }
    if let Some(n) = name {
        j.raw(",\"name\":");
        j.string(n);
    }
    j.raw(",\"r\":");
    j.arr(&ned_to_enu_arr(&reference_point(shape)), 5);
    match motion {
        Motion::Static => {}
        Motion::Velocity(v) => {
            j.raw(",\"velocity\":");
            j.arr(&ned_to_enu_arr(v), 5);
        }
        Motion::Waypoints(w) => {
            j.raw(",\"waypoints\":[");
            for (i, (t, p)) in w.iter().enumerate() {
                j.sep(i);
                let e = ned_to_enu_arr(p);
                j.arr(&[*t, e[0], e[1], e[2]], 5);
            }
            j.raw("]");
        }
    }
    if !o.mapped {
        // Only unmapped obstacles carry the flag (the page's default is mapped).
        j.raw(",\"mapped\":false");
    }
    j.raw("}");
}

/// `summary.json` flattened to `[key, text]` pairs (`params.mu`, …), each text as serde_json
/// writes the value in the file.
fn summary_pairs(j: &mut Json, s: &super::Summary) {
    let v = serde_json::to_value(s).unwrap_or(serde_json::Value::Null);
    let mut pairs = Vec::new();
    flatten("", &v, &mut pairs);
    for (i, (k, t)) in pairs.iter().enumerate() {
        j.sep(i);
        j.raw("[");
        j.string(k);
        j.raw(",");
        j.string(t);
        j.raw("]");
    }
}

fn flatten(prefix: &str, v: &serde_json::Value, out: &mut Vec<(String, String)>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                let key = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                flatten(&key, x, out);
            }
        }
        // The file's own text of the value (a string keeps its quotes off).
        serde_json::Value::String(s) => out.push((prefix.to_string(), s.clone())),
        other => out.push((prefix.to_string(), other.to_string())),
    }
}

/// A JSON text being written.
struct Json(Vec<u8>);

impl Json {
    fn raw(&mut self, s: &str) {
        self.0.extend_from_slice(s.as_bytes());
    }
    fn sep(&mut self, i: usize) {
        if i > 0 {
            self.0.push(b',');
        }
    }
    /// A string; `<` escaped so the text cannot close the script element.
    fn string(&mut self, s: &str) {
        let text = serde_json::to_string(s).unwrap_or_else(|_| "\"\"".into());
        self.raw(&text.replace('<', "\\u003c"));
    }
    /// `x` with `d` decimals as the report files write it; non-finite values as the strings
    /// the files hold (`"NaN"`, `"inf"`, `"-inf"`).
    fn num(&mut self, x: f64, d: usize) {
        if x.is_finite() {
            push_fixed(&mut self.0, x, d);
        } else {
            self.raw(&format!("\"{x:.d$}\""));
        }
    }
    fn arr(&mut self, a: &[f64], d: usize) {
        self.raw("[");
        for (i, x) in a.iter().enumerate() {
            self.sep(i);
            self.num(*x, d);
        }
        self.raw("]");
    }
    /// A scene value (an `f32` as read): its shortest text.
    fn f32(&mut self, x: f32) {
        if x.is_finite() {
            self.raw(&format!("{x}"));
        } else {
            self.raw("null");
        }
    }
    /// ENU values of a scene `f32` triple (converted exactly: swap and negate).
    fn arr_f32(&mut self, a: &[f64; 3]) {
        self.raw("[");
        for (i, x) in a.iter().enumerate() {
            self.sep(i);
            self.f32(*x as f32);
        }
        self.raw("]");
    }
}

mod overlays;
pub use overlays::{
    interventions, Intervention, FAILSAFE_GUIDANCE, MAX_DRAWN_RETURNS, MAX_FILTER_STEPS_SHOWN,
    MAX_SCANS_PER_S,
};

#[cfg(test)]
pub(crate) mod tests;
