"""A mesh viewer in one self-contained HTML file.

:func:`viewer_html` writes the meshes, side by side, into one page that any browser
opens without a network: the vertex, face, normal and colour arrays are embedded as
base64, and a small WebGL2 renderer (written here, no library) draws them.  Dragging
in any panel rotates every panel alike, the wheel zooms them alike, and the page
switches between flat shading (the normal of each face, from screen-space
derivatives) and smooth shading (area-weighted vertex normals, as
:func:`jaxmesh.geometry.vertex_normals`).  A per-vertex scalar (e.g. the distance to
a reference, :func:`vertex_distances`) colours the meshes on one shared scale, with a
legend.

Every panel uses the frame of the first mesh (its bounding-box centre and diagonal),
so meshes that overlap in space overlap on screen too; at the start (and after a
double-click) that mesh's bounding sphere fits the shorter side of each panel, so a
long model is never cropped in a narrow panel, whatever its rotation.  If the page fails (no
WebGL2, a shader error) it says so in the page and on the browser console, and the
``<body>`` carries ``data-status="error"``; when every panel is drawn it carries
``data-status="drawn"``.
"""

from __future__ import annotations

import base64
import html
import json
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .geometry import vertex_normals
from .io import write_bytes_atomic
from .mesh import Mesh

__all__ = ["viewer_html", "write_viewer", "vertex_distances", "SHADINGS"]

SHADINGS = ("flat", "smooth")

#: colour ramp of the scalar colouring: (position, RGB) stops, dark blue to yellow
#: (perceptually ordered, after the viridis family)
_RAMP = np.array([[0.0, 0.267, 0.005, 0.329], [0.25, 0.229, 0.322, 0.546], [0.5, 0.128, 0.567, 0.551],
                  [0.75, 0.369, 0.789, 0.383], [1.0, 0.993, 0.906, 0.144]])


def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()).decode("ascii")


def ramp(t: np.ndarray) -> np.ndarray:
    """The viewer's colour ramp (dark blue to yellow, after the viridis family).

    Arguments:
        t: values in [0, 1] (clipped).

    Returns:
        RGB in [0, 1], shape ``t.shape + (3,)``."""
    t = np.clip(np.asarray(t, np.float64), 0, 1)
    return np.stack([np.interp(t, _RAMP[:, 0], _RAMP[:, k]) for k in (1, 2, 3)], axis=-1)


def vertex_distances(reference: Mesh, mesh: Mesh) -> np.ndarray:
    """Distance of each vertex of ``mesh`` to ``reference``.

    Arguments:
        reference: the reference mesh.
        mesh: the mesh whose vertices are measured.

    Returns:
        (V,) float64: to the corresponding vertex when both meshes have the same
        number of vertices (a denoised or attacked copy), else to the closest point
        of the reference's surface."""
    v = np.asarray(mesh.vertices, np.float64)
    r = np.asarray(reference.vertices, np.float64)
    if v.shape == r.shape:
        return np.linalg.norm(v - r, axis=-1)
    from .metrics import _point_surface_distance

    return _point_surface_distance(v, r, np.asarray(reference.faces))


def _panel(label: str, mesh: Mesh, centre: np.ndarray, scale: float, colors) -> dict:
    if mesh.batch_shape:
        raise ValueError(f"{label}: the viewer draws single meshes, got batch shape {mesh.batch_shape}")
    v = (np.asarray(mesh.vertices, np.float64) - centre[None, :]) / scale
    n = np.asarray(vertex_normals(mesh, "area"), np.float64)
    out = {"label": label, "vertices": _b64(v.astype(np.float32)), "normals": _b64(n.astype(np.float32)),
           "faces": _b64(np.asarray(mesh.faces, np.uint32)), "num_vertices": int(mesh.num_vertices),
           "num_faces": int(mesh.num_faces)}
    if colors is not None:
        out["colors"] = _b64(np.round(255 * colors).astype(np.uint8))
    return out


def viewer_html(meshes: Sequence[tuple[str, Mesh]], scalars: Sequence[np.ndarray | None] | None = None, *,
                shading: str = "flat", title: str = "jaxmesh view", scalar_label: str = "value",
                scalar_range: tuple[float, float] | None = None) -> str:
    """The HTML page (a string) showing ``meshes`` — (label, mesh) pairs — side by side.

    Arguments:
        meshes: the (label, single mesh) pairs, drawn left to right.
        scalars: one per mesh, ``None`` or a per-vertex array of its vertex count;
            the meshes that have one are coloured on one shared scale.
        shading: ``"flat"`` or ``"smooth"`` at first (the page has a switch).
        title: the page title.
        scalar_label: the legend's name for the scalar.
        scalar_range: (low, high) of the colour scale; default the smallest value
            and the largest 99th percentile over the meshes.

    Returns:
        The page, one self-contained HTML document.
    """
    meshes = list(meshes)
    if not meshes:
        raise ValueError("the viewer needs at least one mesh")
    if shading not in SHADINGS:
        raise ValueError(f"shading must be one of {SHADINGS}, got {shading!r}")
    for k, item in enumerate(meshes):
        if not (isinstance(item, tuple) and len(item) == 2 and isinstance(item[1], Mesh)):
            raise TypeError(f"meshes[{k}] must be a (label, jaxmesh.Mesh) pair")
    scalars = [None] * len(meshes) if scalars is None else list(scalars)
    if len(scalars) != len(meshes):
        raise ValueError(f"got {len(scalars)} scalar arrays for {len(meshes)} meshes")
    values = []
    for (label, mesh), s in zip(meshes, scalars):
        if s is None:
            values.append(None)
            continue
        s = np.asarray(s, np.float64)
        if s.shape != (mesh.num_vertices,):
            raise ValueError(f"{label}: the scalar has shape {s.shape}, the mesh {mesh.num_vertices} vertices")
        if not np.all(np.isfinite(s)):
            raise ValueError(f"{label}: the scalar has non-finite values")
        values.append(s)
    present = [s for s in values if s is not None]
    if scalar_range is None and present:
        lo = min(float(s.min()) for s in present)
        hi = max(float(np.percentile(s, 99)) for s in present)
    elif present:
        lo, hi = (float(x) for x in scalar_range)
    else:
        lo = hi = 0.0
    span = hi - lo if hi > lo else 1.0

    first = np.asarray(meshes[0][1].vertices, np.float64)
    hi_box, lo_box = first.max(axis=0), first.min(axis=0)
    centre = 0.5 * (hi_box + lo_box)
    scale = float(np.linalg.norm(hi_box - lo_box)) or 1.0
    panels = [_panel(label, mesh, centre, scale, None if s is None else ramp((s - lo) / span))
              for (label, mesh), s in zip(meshes, values)]
    config = {"panels": panels, "shading": shading,
              "legend": {"label": scalar_label, "low": lo, "high": hi,
                         "stops": [[float(x) for x in row] for row in _RAMP]} if present else None}
    return (_PAGE.replace("__TITLE__", html.escape(title))
            .replace("__DATA__", json.dumps(config, separators=(",", ":")).replace("</", "<\\/")))


def write_viewer(path: str | os.PathLike, meshes: Sequence[tuple[str, Mesh]],
                 scalars: Sequence[np.ndarray | None] | None = None, *, overwrite: bool = False, **options) -> Path:
    """Write :func:`viewer_html` to ``path`` atomically.

    Arguments:
        path: the HTML file.
        meshes: (label, mesh) pairs, as for :func:`viewer_html`.
        scalars: one per mesh, ``None`` or a per-vertex array.
        overwrite: replace an existing file (default: refuse).
        **options: ``shading``, ``title``, ``scalar_label``, ``scalar_range`` of
            :func:`viewer_html`.

    Returns:
        The path written."""
    page = viewer_html(meshes, scalars, **options)
    return write_bytes_atomic(path, page.encode("utf-8"), overwrite=overwrite)


_PAGE = r"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>__TITLE__</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>
html, body { margin: 0; height: 100%; background: #ffffff; font: 13px/1.4 system-ui, sans-serif; color: #222; }
#bar { display: flex; gap: 1.2em; align-items: center; padding: 6px 10px; border-bottom: 1px solid #ddd; }
#bar .title { font-weight: 600; }
#panels { display: flex; height: calc(100% - 64px); }
.panel { flex: 1 1 0; display: flex; flex-direction: column; min-width: 0; border-right: 1px solid #eee; }
.panel:last-child { border-right: none; }
.panel .label { padding: 3px 8px; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
.panel canvas { flex: 1 1 auto; width: 100%; min-height: 0; cursor: grab; touch-action: none; }
#legend { display: flex; align-items: center; gap: 6px; }
#legend canvas { width: 160px; height: 12px; border: 1px solid #ccc; }
#error { display: none; color: #a00; padding: 10px; white-space: pre-wrap; }
</style></head>
<body data-status="loading">
<div id="bar"><span class="title">__TITLE__</span>
<label><input type="checkbox" id="flat"> flat shading</label>
<span>drag: rotate &middot; wheel: zoom &middot; double-click: reset</span>
<span id="legend"></span></div>
<div id="error"></div>
<div id="panels"></div>
<script type="application/json" id="data">__DATA__</script>
<script>
"use strict";
(function () {
  function fail(message) {
    document.body.dataset.status = "error";
    var box = document.getElementById("error");
    box.style.display = "block";
    box.textContent = "jaxmesh view: " + message;
    console.error("jaxmesh view: " + message);
  }
  window.addEventListener("error", function (e) { fail(e.message || String(e)); });

  function decode(b64, Type) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Type(bytes.buffer);
  }
  // 3x3 rotations, row-major arrays of 9
  function mul(a, b) {
    var c = new Array(9);
    for (var i = 0; i < 3; i++) for (var j = 0; j < 3; j++)
      c[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
    return c;
  }
  function rotX(t) { var c = Math.cos(t), s = Math.sin(t); return [1, 0, 0, 0, c, -s, 0, s, c]; }
  function rotY(t) { var c = Math.cos(t), s = Math.sin(t); return [c, 0, s, 0, 1, 0, -s, 0, c]; }
  var HOME = mul(rotX(0.35), rotY(-0.5));
  var view = { rot: HOME.slice(), zoom: 1.0 };
  // the field of view spans the panel's shorter side; at zoom 1 the first mesh's bounding
  // sphere (radius: half its diagonal, 0.5 in the page's frame) fits it, in any rotation
  var FOV = 0.6, FIT = 0.52 / Math.sin(0.5 * FOV);

  var VS = "#version 300 es\n" +
    "in vec3 aPos; in vec3 aNormal; in vec3 aColor;\n" +
    "uniform mat3 uRot; uniform float uDist; uniform float uFocal; uniform float uAspect;\n" +
    "out vec3 vPos; out vec3 vNormal; out vec3 vColor;\n" +
    "void main() {\n" +
    "  vec3 p = uRot * aPos; p.z -= uDist; vPos = p; vNormal = uRot * aNormal; vColor = aColor;\n" +
    "  float near = 0.01, far = 100.0;\n" +
    "  gl_Position = vec4(p.x * uFocal / max(uAspect, 1.0), p.y * uFocal * min(uAspect, 1.0),\n" +
    "                     (p.z * (far + near) + 2.0 * far * near) / (near - far), -p.z);\n" +
    "}\n";
  var FS = "#version 300 es\nprecision highp float;\n" +
    "in vec3 vPos; in vec3 vNormal; in vec3 vColor; uniform int uFlat; out vec4 outColor;\n" +
    "void main() {\n" +
    "  vec3 n = uFlat == 1 ? normalize(cross(dFdx(vPos), dFdy(vPos))) : normalize(vNormal);\n" +
    "  vec3 l = normalize(-vPos); float d = abs(dot(n, l));\n" +
    "  vec3 base = gl_FrontFacing ? vColor : 0.75 * vColor;\n" +
    "  outColor = vec4(base * (0.3 + 0.7 * d) + vec3(0.06) * pow(d, 24.0), 1.0);\n" +
    "}\n";

  function compile(gl, type, src) {
    var s = gl.createShader(type);
    gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
    return s;
  }

  function Panel(spec, parent) {
    var div = document.createElement("div"); div.className = "panel";
    var label = document.createElement("div"); label.className = "label";
    label.textContent = spec.label + "  (" + spec.num_vertices + " vertices, " + spec.num_faces + " faces)";
    label.title = spec.label;
    var canvas = document.createElement("canvas");
    div.appendChild(label); div.appendChild(canvas); parent.appendChild(div);
    var gl = canvas.getContext("webgl2", { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error("this browser has no WebGL2");
    var prog = gl.createProgram();
    gl.attachShader(prog, compile(gl, gl.VERTEX_SHADER, VS));
    gl.attachShader(prog, compile(gl, gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(prog);
    if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(prog));
    gl.useProgram(prog);
    function attribute(name, data, size, normalized) {
      var loc = gl.getAttribLocation(prog, name), buf = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buf); gl.bufferData(gl.ARRAY_BUFFER, data, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, data instanceof Uint8Array ? gl.UNSIGNED_BYTE : gl.FLOAT, !!normalized, 0, 0);
    }
    var vao = gl.createVertexArray(); gl.bindVertexArray(vao);
    attribute("aPos", decode(spec.vertices, Float32Array), 3);
    attribute("aNormal", decode(spec.normals, Float32Array), 3);
    if (spec.colors) attribute("aColor", decode(spec.colors, Uint8Array), 3, true);
    else gl.vertexAttrib3f(gl.getAttribLocation(prog, "aColor"), 0.72, 0.76, 0.84);
    var faces = decode(spec.faces, Uint32Array);
    var ibo = gl.createBuffer();
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo); gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, faces, gl.STATIC_DRAW);
    var count = faces.length;
    var u = {};
    ["uRot", "uDist", "uFocal", "uAspect", "uFlat"].forEach(function (n) { u[n] = gl.getUniformLocation(prog, n); });

    this.canvas = canvas;
    this.draw = function () {
      var dpr = window.devicePixelRatio || 1;
      var w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
      if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
      gl.viewport(0, 0, w, h);
      gl.clearColor(1, 1, 1, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
      gl.enable(gl.DEPTH_TEST);
      gl.useProgram(prog); gl.bindVertexArray(vao);
      var r = view.rot;   // row-major -> column-major for GLSL
      gl.uniformMatrix3fv(u.uRot, false, [r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8]]);
      gl.uniform1f(u.uDist, FIT / view.zoom);
      gl.uniform1f(u.uFocal, 1.0 / Math.tan(0.5 * FOV));
      gl.uniform1f(u.uAspect, w / h);
      gl.uniform1i(u.uFlat, document.getElementById("flat").checked ? 1 : 0);
      gl.drawElements(gl.TRIANGLES, count, gl.UNSIGNED_INT, 0);
      var err = gl.getError();
      if (err !== gl.NO_ERROR) throw new Error("WebGL error " + err + " drawing " + spec.label);
    };
  }

  function legend(spec) {
    if (!spec) return;
    var box = document.getElementById("legend");
    var bar = document.createElement("canvas"); bar.width = 160; bar.height = 12;
    var ctx = bar.getContext("2d"), grad = ctx.createLinearGradient(0, 0, 160, 0);
    spec.stops.forEach(function (s) {
      grad.addColorStop(s[0], "rgb(" + [s[1], s[2], s[3]].map(function (x) { return Math.round(255 * x); }).join(",") + ")");
    });
    ctx.fillStyle = grad; ctx.fillRect(0, 0, 160, 12);
    function fmt(x) { return Math.abs(x) >= 1e-3 && Math.abs(x) < 1e4 ? x.toPrecision(3) : x.toExponential(2); }
    box.appendChild(document.createTextNode(spec.label + ": " + fmt(spec.low)));
    box.appendChild(bar);
    box.appendChild(document.createTextNode(fmt(spec.high) + " (and above)"));
  }

  try {
    var config = JSON.parse(document.getElementById("data").textContent);
    document.getElementById("flat").checked = config.shading === "flat";
    legend(config.legend);
    var holder = document.getElementById("panels");
    var panels = config.panels.map(function (p) { return new Panel(p, holder); });
    var drawAll = function () { panels.forEach(function (p) { p.draw(); }); };
    var drag = null;
    panels.forEach(function (p) {
      p.canvas.addEventListener("pointerdown", function (e) { drag = [e.clientX, e.clientY]; p.canvas.setPointerCapture(e.pointerId); });
      p.canvas.addEventListener("pointermove", function (e) {
        if (!drag) return;
        var dx = e.clientX - drag[0], dy = e.clientY - drag[1]; drag = [e.clientX, e.clientY];
        view.rot = mul(mul(rotX(0.01 * dy), rotY(0.01 * dx)), view.rot); drawAll();
      });
      p.canvas.addEventListener("pointerup", function () { drag = null; });
      p.canvas.addEventListener("wheel", function (e) {
        e.preventDefault(); view.zoom = Math.min(20, Math.max(0.2, view.zoom * Math.exp(-0.001 * e.deltaY))); drawAll();
      }, { passive: false });
      p.canvas.addEventListener("dblclick", function () { view.rot = HOME.slice(); view.zoom = 1.0; drawAll(); });
    });
    document.getElementById("flat").addEventListener("change", drawAll);
    window.addEventListener("resize", drawAll);
    drawAll();
    if (document.body.dataset.status !== "error") document.body.dataset.status = "drawn";
  } catch (e) {
    fail(e && e.message ? e.message : String(e));
  }
})();
</script>
</body></html>
"""
