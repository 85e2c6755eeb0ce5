"""The page elements the viewer's script reads, stubbed for running viewer.js under node (tests of the
report's viewer: tests/viz/test_render_walls.py, test_routes.py). `ctx`, the recording canvas context,
is the harness's own."""

ELEMENTS = r"""
const els = {};
function el(id) {
  if (!els[id]) {
    els[id] = { id, value: "", checked: true, max: "0", textContent: "", children: [],
      width: 600, height: 600,
      appendChild(c) { this.children.push(c); if (!this.value) this.value = c.value; },
      addEventListener() {}, getContext: () => ctx };
    Object.defineProperty(els[id], "innerHTML",
      { set(v) { this.children = []; this.value = ""; }, get() { return ""; } });
  }
  return els[id];
}
"""
