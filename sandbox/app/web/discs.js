// The page's 2D picture: a particle frame (sandbox/render/particle_frame.py) drawn with Canvas 2D over the picture
// without its particles, as the sandbox's renderer draws it (sandbox/render/flat.py): the springs' lines where the
// scene draws them, then every particle's disc in painter's order.
"use strict";

// a particle frame: a 21-byte header (kind, frame, seq, time, n), then three u32 a particle: x | y << 16 (pixels
// x 16, rows from the top), r | kind << 16 (pixels x 16), R | G << 8 | B << 16 | A << 24; drawn as the renderer's
// discs (opaque ones with their coverage, translucent ones with their opacity), in order
function drawParticles(context, buffer) {
  const view = new DataView(buffer);
  const n = view.getUint32(17, true);
  const records = new Uint32Array(buffer.slice(21, 21 + 12 * n));
  if (buffer.byteLength > 21 + 12 * n) drawSprings(context, buffer, records, 21 + 12 * n);
  for (let i = 0; i < n; i++) {
    const place = records[3 * i], size = records[3 * i + 1], colour = records[3 * i + 2];
    if ((size >>> 16) === 2) continue;  // a glowing particle: its light comes in the light frame (light.js)
    const alpha = (colour >>> 24) / 255;
    context.fillStyle = `rgba(${colour & 255},${(colour >>> 8) & 255},${(colour >>> 16) & 255},${alpha.toFixed(3)})`;
    context.beginPath();
    context.arc((place & 0xffff) / 16, (place >>> 16) / 16, Math.max((size & 0xffff) / 16, 0.5), 0, 2 * Math.PI);
    context.fill();
  }
}

// the springs' lines after the records at `at`: m, their colour, m pairs of particles; each a line a pixel wide,
// "over" the others (as the renderer's transmittances multiply), none across a periodic box's wrap
function drawSprings(context, buffer, records, at) {
  const view = new DataView(buffer);
  const m = view.getUint32(at, true);
  const [r, g, b, a] = new Uint8Array(buffer.slice(at + 4, at + 8));
  const pairs = new Uint32Array(buffer.slice(at + 8, at + 8 + 8 * m));
  const far = 0.25 * Math.max(context.canvas.width, context.canvas.height);
  context.strokeStyle = `rgba(${r},${g},${b},${(a / 255).toFixed(3)})`;
  context.lineWidth = 1;
  for (let k = 0; k < m; k++) {
    const p = records[3 * pairs[2 * k]], q = records[3 * pairs[2 * k + 1]];
    const [x0, y0, x1, y1] = [(p & 0xffff) / 16, (p >>> 16) / 16, (q & 0xffff) / 16, (q >>> 16) / 16];
    if (Math.hypot(x1 - x0, y1 - y0) >= far) continue;
    context.beginPath();
    context.moveTo(x0, y0);
    context.lineTo(x1, y1);
    context.stroke();
  }
}
