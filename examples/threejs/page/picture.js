// One PNG per light for a person: per camera a row of (all casters | kept casters |
// difference), the difference panel a grey copy of the "all" frame with each differing
// pixel coloured by its class (drawn 3 px wide so that a lone pixel shows), false-cull
// and band pixels ringed.

import { BAND, CULLED_SURFACE, FALSE_CULL, NOT_RECEIVING } from './classify.js';

const MARKS = {
  [FALSE_CULL]: [255, 30, 30],
  [BAND]: [255, 170, 0],
  [CULLED_SURFACE]: [40, 110, 190],
  [NOT_RECEIVING]: [230, 60, 230],
};
const LEGEND = [
  [FALSE_CULL, 'false cull'],
  [BAND, 'texel-edge band'],
  [CULLED_SURFACE, "culled caster's own surface"],
  [NOT_RECEIVING, 'not lit by the rules'],
];
const GAP = 6;
const TITLE = 40;
const CAPTION = 20;
const css = ([r, g, b]) => `rgb(${r},${g},${b})`;

// rgba rows bottom first (GL, and the difference image made from GL rows) -> ImageData
// rows top first.
function toImageData(rgba, width, height) {
  const image = new ImageData(width, height);
  for (let y = 0; y < height; y++) image.data.set(rgba.subarray((height - 1 - y) * width * 4, (height - y) * width * 4), y * width * 4);
  return image;
}

function differenceImage(all, classes, width, height) {
  const out = new Uint8ClampedArray(width * height * 4);
  for (let k = 0; k < width * height; k++) {
    const grey = 0.3 * (0.3 * all[4 * k] + 0.59 * all[4 * k + 1] + 0.11 * all[4 * k + 2]);
    out.set([grey, grey, grey, 255], 4 * k);
  }
  // Marks after the grey, in order of importance, so a false cull is never painted over.
  for (const cls of [NOT_RECEIVING, CULLED_SURFACE, BAND, FALSE_CULL])
    for (let k = 0; k < classes.length; k++) {
      if (classes[k] !== cls) continue;
      const x = k % width;
      const y = Math.floor(k / width);
      for (let dy = -1; dy <= 1; dy++)
        for (let dx = -1; dx <= 1; dx++) {
          const xx = x + dx;
          const yy = y + dy;
          if (xx >= 0 && yy >= 0 && xx < width && yy < height) out.set([...MARKS[cls], 255], 4 * (yy * width + xx));
        }
    }
  return out;
}

// Rings around the pixels that matter (false cull, band), one per 12 px cell they fall in,
// so that a handful of pixels reads at a glance in a large panel.
function ringMarks(g, classes, width, height, left, top) {
  const CELL = 12;
  for (const cls of [BAND, FALSE_CULL]) {
    const cells = new Set();
    for (let k = 0; k < classes.length; k++) {
      if (classes[k] !== cls) continue;
      const x = k % width;
      const y = height - 1 - Math.floor(k / width); // GL rows are bottom first
      cells.add(`${Math.floor(x / CELL)},${Math.floor(y / CELL)}`);
    }
    g.strokeStyle = css(MARKS[cls]);
    g.lineWidth = 2;
    for (const cell of cells) {
      const [cx, cy] = cell.split(',').map(Number);
      g.beginPath();
      g.arc(left + (cx + 0.5) * CELL, top + (cy + 0.5) * CELL, CELL, 0, 2 * Math.PI);
      g.stroke();
    }
  }
}

// rows: [{ all, kept, classes, caption }], one per camera. Returns a PNG data URL.
export function composePicture(title, rows, width, height) {
  const canvas = document.createElement('canvas');
  canvas.width = 3 * width + 4 * GAP;
  canvas.height = TITLE + rows.length * (CAPTION + height + GAP) + GAP;
  const g = canvas.getContext('2d');
  g.fillStyle = '#111';
  g.fillRect(0, 0, canvas.width, canvas.height);
  g.font = '14px monospace';
  g.fillStyle = '#eee';
  g.fillText(title, GAP, 17);
  let x = GAP;
  g.font = '12px monospace';
  for (const [cls, text] of LEGEND) {
    g.fillStyle = css(MARKS[cls]);
    g.fillRect(x, 26, 10, 10);
    g.fillStyle = '#ccc';
    g.fillText(text, x + 14, 35);
    x += 24 + g.measureText(text).width;
  }
  rows.forEach((row, r) => {
    const top = TITLE + r * (CAPTION + height + GAP);
    g.fillStyle = '#ccc';
    g.fillText(row.caption, GAP, top + 14);
    const panels = [row.all, row.kept, differenceImage(row.all, row.classes, width, height)];
    const labels = ['all casters', 'kept casters', 'difference'];
    panels.forEach((rgba, c) => {
      const left = GAP + c * (width + GAP);
      g.putImageData(toImageData(rgba, width, height), left, top + CAPTION);
      if (c === 2) ringMarks(g, row.classes, width, height, left, top + CAPTION);
      g.fillStyle = 'rgba(0,0,0,0.6)';
      g.fillRect(left, top + CAPTION, g.measureText(labels[c]).width + 8, 16);
      g.fillStyle = '#fff';
      g.fillText(labels[c], left + 4, top + CAPTION + 12);
    });
  });
  return canvas.toDataURL('image/png');
}
