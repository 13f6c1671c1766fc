"""The pages' CustomJS callbacks (Bokeh runs them in the browser; the names in each are the
``args`` the Python side passes)."""

FILTER = """
// the requirement sliders: fade the front's policies that miss a requirement, draw the box
const data = source.data;
const n = data.policy.length;
const alpha = new Array(n).fill(1.0);
let count = n;
for (let p = 0; p < n; p++) {
  for (let s = 0; s < sliders.length; s++) {
    const v = data[keys[s]][p];
    const k = names.indexOf(keys[s]);
    const ok = v !== null && (maximise[k] ? v >= sliders[s].value : v <= sliders[s].value);
    if (!ok) { alpha[p] = 0.12; count -= 1; break; }
  }
}
data.alpha = alpha;
source.change.emit();
for (let s = 0; s < sliders.length; s++) {
  const k = names.indexOf(keys[s]);
  const edge = maximise[k] ? "low" : "high";
  if (keys[s] === axes[0]) { box[edge === "low" ? "left" : "right"] = sliders[s].value; }
  if (keys[s] === axes[1]) { box[edge === "low" ? "bottom" : "top"] = sliders[s].value; }
}
counter.text = count + " of " + n + " points meet the requirements";
"""

_NEAREST_OF = """
// the index among ``hits`` of the point nearest to (gx, gy), measured in screen proportions
function nearest_of(hits, gx, gy) {
  const data = source.data;
  const wx = (xr.end - xr.start) / width, wy = (yr.end - yr.start) / height;
  let best = hits[0], distance = Infinity;
  for (const i of hits) {
    const dx = (data.x[i] - gx) / wx, dy = (data.y[i] - gy) / wy;
    const d = dx * dx + dy * dy;
    if (d < distance) { distance = d; best = i; }
  }
  return best;
}
"""

SHOW_POLICY = (
    _NEAREST_OF
    + """
// a click on the front (the tap tool's callback): the nearest of the points under the
// pointer is chosen, and its policy's decisions go into the table (and the maps)
const chosen = source.selected.indices;
if (chosen.length === 0) { return; }
let p = chosen[0];
if (chosen.length > 1) {
  const g = Array.isArray(cb_data.geometries) ? cb_data.geometries[0] : cb_data.geometries;
  if (g !== undefined) { p = nearest_of(chosen, g.x, g.y); }
  source.selected.indices = [p];
}
const values = decisions[p];
const columns = table.data;
for (let d = 0; d < values.length; d++) {
  columns[constant_of[d]][row_of[d]] = values[d];
}
table.change.emit();
// Bokeh's DataTable redraws the rows it shows only when the table itself changes, not when
// its source's data does (the rows stayed the previous policy's until scrolled)
grid_table.change.emit();
const parts = names.map((name) => name + " " + Number(source.data[name][p]).toPrecision(6));
const tied = source.data.ties[p] > 0 ? " (ties with " + source.data.others[p] + ")" : "";
heading.text = "<b>policy " + source.data.policy[p] + "</b>" + tied + ": " + parts.join(", ");
"""
)

NEAREST = (
    _NEAREST_OF
    + """
// hovering the front: the one point nearest the pointer, not every point under it, in the
// readout below the plot and ringed on the plot
const hits = cb_data.index.indices;
if (hits.length === 0) { return; }
const data = source.data;
const best = nearest_of(hits, cb_data.geometry.x, cb_data.geometry.y);
ring.data = {x: [data.x[best]], y: [data.y[best]]};
const parts = names.map((name) => name + " " + Number(data[name][best]).toPrecision(6));
const tied = data.ties[best] > 0 ? " (+" + data.ties[best] + " tied)" : "";
readout.text = "<b>" + data.policy[best] + "</b>" + tied + ": " + parts.join(", ");
"""
)

CHOOSE_SETTING = """
// the requirement setting chosen: each box plot's data becomes that setting's
const chosen = cb_obj.value;
for (let k = 0; k < sources.length; k++) {
  sources[k].data = every[k][chosen];
}
"""

SLICE = """
// a menu of an observation variable the grid does not show: draw that value's cells
const data = source.data;
const n = data[variables[0]].length;
const wanted = menus.map((menu) => Number(menu.value));
const booleans = new Array(n);
for (let r = 0; r < n; r++) {
  booleans[r] = variables.every((v, k) => data[v][r] === wanted[k]);
}
filter.booleans = booleans;
source.change.emit();
"""
