"use strict";
// Rotation of real SH coefficients for any band count, in double precision: the same
// Ivanic-Ruedenberg recurrence as src/sh/rotation.rs (J. Phys. Chem. 100, 6342 (1996), with
// the 1998 erratum), so a light turned in the page is the light `prt-gpu light --rotate` writes.
// The recurrence runs in the paper's basis (no Condon-Shortley phase); each finished block is
// changed to ours by flipping the sign of entries (m, n) with m + n odd.
// Rotating a light by R moves whatever it had at direction d to R d.

// Entry (m, n) of band l's (2l+1) x (2l+1) block, row-major, -l <= m, n <= l.
function shBlockIndex(l, m, n) {
  return (m + l) * (2 * l + 1) + (n + l);
}

// The world axis (x 0, y 1, z 2) the paper's band-1 function y'_1m is proportional to.
function shBand1Axis(m) {
  return m === -1 ? 1 : m === 0 ? 2 : 0;
}

// Recurrence coefficients (u, v, w) of Ivanic-Ruedenberg Table 1.
function shUvw(l, m, n) {
  const d = m === 0 ? 1 : 0;
  const am = Math.abs(m);
  const denom = Math.abs(n) === l ? 2 * l * (2 * l - 1) : (l + n) * (l - n);
  const u = Math.sqrt(((l + m) * (l - m)) / denom);
  const v = 0.5 * Math.sqrt(((1 + d) * (l + am - 1) * (l + am)) / denom) * (1 - 2 * d);
  const w = -0.5 * Math.sqrt(((l - am - 1) * (l - am)) / denom) * (1 - d);
  return [u, v, w];
}

// The paper's P^l_{i; a, b}: band-1 row i against band l - 1; the edge columns b = +-l,
// absent from band l - 1, combine its two edge columns.
function shP(i, l, a, b, r1, prev) {
  const r = (m, n) => r1[shBlockIndex(1, m, n)];
  const q = (m, n) => prev[shBlockIndex(l - 1, m, n)];
  if (b === l) return r(i, 1) * q(a, l - 1) - r(i, -1) * q(a, 1 - l);
  if (b === -l) return r(i, 1) * q(a, 1 - l) + r(i, -1) * q(a, l - 1);
  return r(i, 0) * q(a, b);
}

function shV(l, m, n, r1, prev) {
  const delta = (a, b) => (a === b ? 1 : 0);
  if (m === 0) return shP(1, l, 1, n, r1, prev) + shP(-1, l, -1, n, r1, prev);
  if (m > 0) {
    return shP(1, l, m - 1, n, r1, prev) * Math.sqrt(1 + delta(m, 1))
      - shP(-1, l, 1 - m, n, r1, prev) * (1 - delta(m, 1));
  }
  return shP(1, l, m + 1, n, r1, prev) * (1 - delta(m, -1))
    + shP(-1, l, -m - 1, n, r1, prev) * Math.sqrt(1 + delta(m, -1));
}

function shW(l, m, n, r1, prev) {
  if (m > 0) return shP(1, l, m + 1, n, r1, prev) + shP(-1, l, -m - 1, n, r1, prev);
  return shP(1, l, m - 1, n, r1, prev) - shP(-1, l, 1 - m, n, r1, prev);
}

// Band l >= 2 in the paper's basis: D = u U + v V + w W (a zero coefficient's term has
// indices outside band l - 1 and is skipped, not evaluated).
function shNextBlock(l, r1, prev) {
  const block = new Float64Array((2 * l + 1) * (2 * l + 1));
  for (let m = -l; m <= l; m++) {
    for (let n = -l; n <= l; n++) {
      const [u, v, w] = shUvw(l, m, n);
      let value = 0;
      if (u !== 0) value += u * shP(0, l, m, n, r1, prev);
      if (v !== 0) value += v * shV(l, m, n, r1, prev);
      if (w !== 0) value += w * shW(l, m, n, r1, prev);
      block[shBlockIndex(l, m, n)] = value;
    }
  }
  return block;
}

// The blocks of the SH rotation for the 3x3 rotation `rotation` (rows of a row-major matrix),
// in our basis: blocks[l] is band l's block, row-major.
function shRotationBlocks(bands, rotation) {
  const paper = [];
  for (let l = 0; l < bands; l++) {
    if (l === 0) {
      paper.push(Float64Array.of(1));
    } else if (l === 1) {
      const block = new Float64Array(9);
      for (let m = -1; m <= 1; m++) {
        for (let n = -1; n <= 1; n++) {
          block[shBlockIndex(1, m, n)] = rotation[shBand1Axis(m)][shBand1Axis(n)];
        }
      }
      paper.push(block);
    } else {
      paper.push(shNextBlock(l, paper[1], paper[l - 1]));
    }
  }
  return paper.map((block, l) => block.map((value, index) => {
    const m = Math.floor(index / (2 * l + 1)) - l;
    const n = (index % (2 * l + 1)) - l;
    return (m + n) % 2 !== 0 ? -value : value;
  }));
}

// RGB coefficients [[r, g, b], ...] turned by the blocks (band by band, as sh::rotation's
// ShRotation::apply_rgb does).
function shRotateRgb(blocks, coeffs) {
  const out = coeffs.map(() => [0, 0, 0]);
  blocks.forEach((block, l) => {
    const start = l * l;
    const size = 2 * l + 1;
    for (let row = 0; row < size; row++) {
      for (let col = 0; col < size; col++) {
        const d = block[row * size + col];
        const input = coeffs[start + col];
        for (let c = 0; c < 3; c++) out[start + row][c] += d * input[c];
      }
    }
  });
  return out;
}

// R = Ry(yaw) Rx(pitch) Rz(roll), degrees, rows of a row-major matrix: roll about +Z first,
// then pitch about +X, then yaw about +Y (ShRotation::from_yaw_pitch_roll).
function yawPitchRollMatrix(yawDeg, pitchDeg, rollDeg) {
  const rad = Math.PI / 180;
  const [cy, sy] = [Math.cos(yawDeg * rad), Math.sin(yawDeg * rad)];
  const [cp, sp] = [Math.cos(pitchDeg * rad), Math.sin(pitchDeg * rad)];
  const [cr, sr] = [Math.cos(rollDeg * rad), Math.sin(rollDeg * rad)];
  const ry = [[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]];
  const rx = [[1, 0, 0], [0, cp, -sp], [0, sp, cp]];
  const rz = [[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]];
  return matrixProduct(ry, matrixProduct(rx, rz));
}

function matrixProduct(a, b) {
  return a.map((row) => [0, 1, 2].map((j) => row[0] * b[0][j] + row[1] * b[1][j] + row[2] * b[2][j]));
}

// The light turned by yaw, pitch and roll in degrees (ShLight::rotated).
function rotateLight(coeffs, bands, yawPitchRoll) {
  const [yaw, pitch, roll] = yawPitchRoll;
  if (yaw === 0 && pitch === 0 && roll === 0) return coeffs.map((c) => c.slice());
  return shRotateRgb(shRotationBlocks(bands, yawPitchRollMatrix(yaw, pitch, roll)), coeffs);
}
