"use strict";
// Probes: a test sphere moved through the scene, lit as an engine lights a dynamic object —
// the probes around its centre interpolated (trilinear on their grid, leaving invalid ones
// out, as ProbeSet::interpolate; the nearest valid probe without a grid, as
// render::probes_at), that matrix times the light, each row times its clamped-cosine factor:
// the irradiance's SH, which probe_sphere.vert sums for each vertex's normal.

class ProbeField {
  constructor(probes) {
    this.probes = probes;
    this.coeffs = probes.bands * probes.bands;
    this.perProbe = probes.channels * probes.rows * this.coeffs;
    this.positions = decodeBase64(probes.positions, Float32Array);
    this.matrices = decodeBase64(probes.matrices, Float32Array);
    // A flying sphere's path stays in the box of the valid probes.
    const valid = [...Array(probes.count).keys()].filter((p) => probes.valid[p]);
    const axis = (a) => valid.map((p) => this.positions[3 * p + a]);
    this.low = [0, 1, 2].map((a) => Math.min(...axis(a)));
    this.high = [0, 1, 2].map((a) => Math.max(...axis(a)));
  }

  // The matrix at `point` ([channel][row][k]), or null where no valid probe lights it.
  matrixAt(point) {
    return this.probes.grid ? this.trilinear(point, this.probes.grid) : this.nearest(point);
  }

  trilinear(point, grid) {
    const lower = [0, 0, 0];
    const fraction = [0, 0, 0];
    for (let axis = 0; axis < 3; axis++) {
      const last = Math.max(grid.dims[axis] - 1, 0);
      const x = Math.min(Math.max((point[axis] - grid.origin[axis]) / grid.spacing, 0), last);
      const base = Math.min(Math.floor(x), Math.max(last - 1, 0));
      lower[axis] = base;
      fraction[axis] = x - base;
    }
    const out = new Float64Array(this.perProbe);
    let total = 0;
    for (let corner = 0; corner < 8; corner++) {
      const index = [0, 0, 0];
      let weight = 1;
      for (let axis = 0; axis < 3; axis++) {
        const upper = (corner >> axis) & 1;
        index[axis] = Math.min(lower[axis] + upper, grid.dims[axis] - 1);
        weight *= upper ? fraction[axis] : 1 - fraction[axis];
      }
      const p = index[0] + grid.dims[0] * (index[1] + grid.dims[1] * index[2]);
      if (weight === 0 || !this.probes.valid[p]) continue;
      total += weight;
      const from = p * this.perProbe;
      for (let e = 0; e < this.perProbe; e++) out[e] += weight * this.matrices[from + e];
    }
    return total > 0 ? out.map((m) => m / total) : null;
  }

  nearest(point) {
    let best = -1;
    let bestDistance = Infinity;
    for (let p = 0; p < this.probes.count; p++) {
      if (!this.probes.valid[p]) continue;
      const d = sub(point, Array.from(this.positions.subarray(3 * p, 3 * p + 3)));
      if (dot(d, d) < bestDistance) [best, bestDistance] = [p, dot(d, d)];
    }
    return best < 0 ? null : this.matrices.subarray(best * this.perProbe, (best + 1) * this.perProbe);
  }

  // The irradiance's SH coefficients ([row] RGB) at `point` under `light` ([k] RGB, at least
  // the probes' bands), or null where no valid probe lights it. One channel of transfer
  // passes each of the light's colours unchanged.
  irradianceAt(point, light) {
    const matrix = this.matrixAt(point);
    if (!matrix) return null;
    const { rows, channels, rowFactors } = this.probes;
    const n = this.coeffs;
    const out = [];
    for (let i = 0; i < rows; i++) {
      out.push([0, 1, 2].map((rgb) => {
        const from = (Math.min(rgb, channels - 1) * rows + i) * n;
        let sum = 0;
        for (let k = 0; k < n; k++) sum += matrix[from + k] * light[k][rgb];
        return rowFactors[i] * sum;
      }));
    }
    return out;
  }

  // Where a flying sphere is `seconds` into its flight: a slow Lissajous loop through the
  // valid probes' box.
  flightAt(seconds) {
    const phase = [0.31, 0.23, 0.17].map((f) => Math.sin(2 * Math.PI * f * seconds));
    return [0, 1, 2].map((a) => {
      const middle = 0.5 * (this.low[a] + this.high[a]);
      return middle + 0.4 * (this.high[a] - this.low[a]) * phase[a];
    });
  }
}

// The sphere's program and vertex array, for the probes' irradiance bands.
function sphereResources(gl, probes) {
  const bands = Math.round(Math.sqrt(probes.rows));
  const program = compile(gl, `#define SH_BANDS ${bands}`,
    { vertex: ["sh-sum", "probe-sphere-vertex"], fragment: ["tone-map", "mesh-fragment"] });
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ARRAY_BUFFER, decodeBase64(DATA.sphere.positions, Float32Array), gl.STATIC_DRAW);
  const location = gl.getAttribLocation(program, "position");
  gl.enableVertexAttribArray(location);
  gl.vertexAttribPointer(location, 3, gl.FLOAT, false, 0, 0);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, decodeBase64(DATA.sphere.indices, Uint32Array), gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  return { program, vao, at: uniforms(gl, program), field: new ProbeField(probes) };
}
