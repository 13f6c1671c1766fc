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
counter.text = count + " of " + n + " policies meet the requirements";
"""

SHOW_POLICY = """
// a click on the front: the chosen policy's decisions into the table (and the maps)
const chosen = source.selected.indices;
if (chosen.length === 0) { return; }
const p = chosen[0];
const values = decisions[p];
const columns = table.data;
for (let d = 0; d < values.length; d++) {
  columns[constant_of[d]][row_of[d]] = values[d];
}
table.change.emit();
const parts = names.map((name) => name + " " + Number(source.data[name][p]).toPrecision(6));
heading.text = "<b>policy " + source.data.policy[p] + "</b>: " + parts.join(", ");
"""

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
