// The light of a 2D picture's glowing particles (sandbox/render/light_frame.py), added to the page's picture as the
// sandbox's renderer adds it (sandbox/render/flat.py, footprint.py): each particle spreads its light over the pixels
// its streak covers, weight clamp(r + 0.5 - d, 0, 1) (times 0.25 + 0.75 t along a blurred streak), at the intensity
// the server computed from the renderer's own weights; the light adds up in a float buffer (WebGL2) and is tone
// mapped over the picture, 1 - exp(-exposure L) per channel. Returns false where the browser cannot (no WebGL2 or no
// float colour buffers): the page then asks for pictures.
"use strict";

let lightGL = null;  // the WebGL2 state, made at the first light frame (false: this browser cannot)

const LIGHT_VERTEX = `#version 300 es
layout(location = 0) in vec2 corner;
layout(location = 1) in vec4 headTail;
layout(location = 2) in vec4 ctrlRadiusBlurred;
layout(location = 3) in vec4 colourIntensity;
uniform vec2 size;
out vec2 head, tail, ctrl;
out float radius, blurred;
out vec3 light;
void main() {
  head = headTail.xy; tail = headTail.zw; ctrl = ctrlRadiusBlurred.xy;
  radius = ctrlRadiusBlurred.z; blurred = ctrlRadiusBlurred.w;
  light = colourIntensity.rgb * colourIntensity.a;
  vec2 lo = min(min(head, tail), ctrl) - radius - 1.0, hi = max(max(head, tail), ctrl) + radius + 1.0;
  gl_Position = vec4(mix(lo, hi, corner) / size * 2.0 - 1.0, 0.0, 1.0);
}`;

const LIGHT_FRAGMENT = `#version 300 es
precision highp float;
in vec2 head, tail, ctrl;
in float radius, blurred;
in vec3 light;
uniform int curved;
out vec4 added;
vec2 segment(vec2 p, vec2 a, vec2 b) {  // (distance to a-b, parameter of the nearest point: 1 at b)
  vec2 ab = b - a;
  float l2 = dot(ab, ab), t = 1.0;
  if (l2 > 1e-12) t = clamp(dot(p - a, ab) / l2, 0.0, 1.0);
  return vec2(length(p - (a + t * ab)), t);
}
void main() {
  vec2 p = gl_FragCoord.xy, near = segment(p, tail, head);
  if (curved == 1 && blurred > 0.5) {  // the quadratic tail-ctrl-head on four chords, as footprint.curve
    near = vec2(1e30, 1.0);
    vec2 start = tail;
    for (int k = 1; k <= 4; k++) {
      float t = float(k) / 4.0;
      vec2 end = (1.0 - t) * (1.0 - t) * tail + 2.0 * (1.0 - t) * t * ctrl + t * t * head;
      vec2 d = segment(p, start, end);
      if (d.x < near.x) near = vec2(d.x, (float(k - 1) + d.y) / 4.0);
      start = end;
    }
  }
  float w = clamp(radius + 0.5 - near.x, 0.0, 1.0);
  if (blurred > 0.5) w *= 0.25 + 0.75 * near.y;
  added = vec4(light * w, 1.0);
}`;

const TONE_VERTEX = `#version 300 es
void main() { gl_Position = vec4(gl_VertexID == 1 ? 3.0 : -1.0, gl_VertexID == 2 ? 3.0 : -1.0, 0.0, 1.0); }`;

const TONE_FRAGMENT = `#version 300 es
precision highp float;
uniform sampler2D picture, light;
uniform float exposure;
out vec4 colour;
void main() {
  ivec2 at = ivec2(gl_FragCoord.xy);
  vec3 c = texelFetch(picture, at, 0).rgb + 1.0 - exp(-exposure * texelFetch(light, at, 0).rgb);
  colour = vec4(min(c, 1.0), 1.0);
}`;

function lightProgram(gl, vertex, fragment) {
  const program = gl.createProgram();
  for (const [kind, text] of [[gl.VERTEX_SHADER, vertex], [gl.FRAGMENT_SHADER, fragment]]) {
    const shader = gl.createShader(kind);
    gl.shaderSource(shader, text);
    gl.compileShader(shader);
    gl.attachShader(program, shader);
  }
  gl.linkProgram(program);
  return gl.getProgramParameter(program, gl.LINK_STATUS) ? program : null;
}

function lightState(width, height) {
  if (lightGL === null) {
    const canvas = document.createElement("canvas");
    const gl = canvas.getContext("webgl2", { antialias: false, premultipliedAlpha: false, alpha: false });
    const floats = gl && gl.getExtension("EXT_color_buffer_float") && gl.getExtension("EXT_float_blend");
    const deposit = floats && lightProgram(gl, LIGHT_VERTEX, LIGHT_FRAGMENT);
    const tone = floats && lightProgram(gl, TONE_VERTEX, TONE_FRAGMENT);
    if (!deposit || !tone) { lightGL = false; return null; }
    const corners = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, corners);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([0, 0, 1, 0, 0, 1, 1, 1]), gl.STATIC_DRAW);
    lightGL = { canvas, gl, deposit, tone, corners, instances: gl.createBuffer(), width: 0, height: 0,
      picture: gl.createTexture(), light: gl.createTexture(), target: gl.createFramebuffer() };
  }
  if (lightGL === false) return null;
  const s = lightGL, gl = s.gl;
  if (s.width !== width || s.height !== height) {
    s.canvas.width = s.width = width; s.canvas.height = s.height = height;
    for (const texture of [s.picture, s.light]) {
      gl.bindTexture(gl.TEXTURE_2D, texture);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
    }
    gl.bindTexture(gl.TEXTURE_2D, s.light);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, null);
    gl.bindFramebuffer(gl.FRAMEBUFFER, s.target);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, s.light, 0);
    if (gl.checkFramebufferStatus(gl.FRAMEBUFFER) !== gl.FRAMEBUFFER_COMPLETE) { lightGL = false; return null; }
  }
  return s;
}

// the light frame `buffer` added to the picture in `context` (the backdrop and the discs already drawn)
function drawLight(context, buffer) {
  const width = context.canvas.width, height = context.canvas.height;
  const s = lightState(width, height);
  if (s === null) return false;
  const gl = s.gl, view = new DataView(buffer);
  const m = view.getUint32(1, true), exposure = view.getFloat32(5, true), curved = view.getUint32(9, true) & 1;
  const words = buffer.slice(13, 13 + 40 * m), records = new Uint32Array(words), reals = new Float32Array(words);
  const data = new Float32Array(12 * m);  // per particle: head, tail (y up, as GL's), ctrl, r, blurred, colour, intensity
  for (let k = 0; k < m; k++) {
    const at = 10 * k, rgb = records[at + 8];
    data.set([reals[at], height - reals[at + 1], reals[at + 2], height - reals[at + 3], reals[at + 4],
      height - reals[at + 5], (records[at + 6] & 0xffff) / 16, records[at + 6] >>> 16,
      (rgb & 255) / 255, ((rgb >>> 8) & 255) / 255, ((rgb >>> 16) & 255) / 255, reals[at + 7]], 12 * k);
  }
  gl.viewport(0, 0, width, height);
  gl.bindFramebuffer(gl.FRAMEBUFFER, s.target);
  gl.clearColor(0, 0, 0, 0);
  gl.clear(gl.COLOR_BUFFER_BIT);
  if (m > 0) {
    gl.useProgram(s.deposit);
    gl.uniform2f(gl.getUniformLocation(s.deposit, "size"), width, height);
    gl.uniform1i(gl.getUniformLocation(s.deposit, "curved"), curved);
    gl.bindBuffer(gl.ARRAY_BUFFER, s.corners);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 2, gl.FLOAT, false, 0, 0);
    gl.vertexAttribDivisor(0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, s.instances);
    gl.bufferData(gl.ARRAY_BUFFER, data, gl.STREAM_DRAW);
    for (let a = 1; a <= 3; a++) {
      gl.enableVertexAttribArray(a);
      gl.vertexAttribPointer(a, 4, gl.FLOAT, false, 48, 16 * (a - 1));
      gl.vertexAttribDivisor(a, 1);
    }
    gl.enable(gl.BLEND);
    gl.blendFunc(gl.ONE, gl.ONE);
    gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, m);
    gl.disable(gl.BLEND);
  }
  gl.bindFramebuffer(gl.FRAMEBUFFER, null);
  gl.useProgram(s.tone);
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, s.picture);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, true);  // row 0 the bottom one, as gl_FragCoord counts
  gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, context.canvas);
  gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, false);
  gl.activeTexture(gl.TEXTURE1);
  gl.bindTexture(gl.TEXTURE_2D, s.light);
  gl.uniform1i(gl.getUniformLocation(s.tone, "picture"), 0);
  gl.uniform1i(gl.getUniformLocation(s.tone, "light"), 1);
  gl.uniform1f(gl.getUniformLocation(s.tone, "exposure"), exposure);
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  context.drawImage(s.canvas, 0, 0);
  return true;
}
