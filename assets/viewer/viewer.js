"use strict";
// The viewer: reads the embedded bakes and light, draws the selected bake relit per vertex
// (mesh.vert) over a sky: the environment map where the page embeds one (sky_map.frag), else
// the SH light (sky.frag); for a file with probes, a test sphere lit by them (probes.js); and
// turns camera, light, exposure and the sphere with the mouse, the controls or the URL.
// Matches `prt-gpu render` (with --probe-sphere): the same camera (look-at, vertical field of
// view, near and far planes hugging what is drawn), the same dot product, the same tone
// mapping.

const DATA = JSON.parse(document.getElementById("prt-data").textContent);
const TONE_MAPS = ["none", "reinhard", "aces"];
const TRANSFER_WIDTH = 4096; // texels per row of the transfer texture

// ---- Small vector helpers (arrays of three numbers) ----
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const length = (a) => Math.sqrt(dot(a, a));
const normalize = (a) => scale(a, 1 / length(a));

// ---- The state: everything a view depends on, read from and written to the URL ----
// The test sphere of a file with probes: "default" (at the valid probe nearest the middle,
// render's default radius), "off", or { centre, radius } (radius null: the default).
function sphereChoice(text) {
  if (text === "0") return "off";
  const values = numbers(text, 3);
  if (!values) return "default";
  const radius = values.length > 3 && values[3] > 0 ? values[3] : null;
  return { centre: values.slice(0, 3), radius };
}

function numbers(text, count) {
  if (text === null) return null;
  const values = text.split(",").map(Number);
  return values.length >= count && values.every(Number.isFinite) ? values : null;
}

function initialState(params) {
  const cam = numbers(params.get("cam"), 6);
  const camera = cam
    ? { eye: cam.slice(0, 3), target: cam.slice(3, 6), fov: cam.length > 6 ? cam[6] : DATA.camera.fov }
    : { eye: DATA.camera.eye, target: DATA.camera.target, fov: DATA.camera.fov };
  const rot = numbers(params.get("rot"), 3);
  const file = Number(params.get("file") ?? 0);
  const tone = params.get("tone") ?? "reinhard";
  return {
    camera,
    rotation: rot ? rot.slice(0, 3) : [0, 0, 0],
    exposure: Number(params.get("exposure") ?? 0) || 0,
    tone: TONE_MAPS.includes(tone) ? tone : "reinhard",
    file: Number.isInteger(file) && file >= 0 && file < DATA.bakes.length ? file : 0,
    sky: skyChoice(params.get("sky")),
    sphere: sphereChoice(params.get("sphere")),
    fly: params.get("fly") === "1",
    zonal: params.get("zonal") === "1",
    bend: bendChoice(params.get("bend")),
  };
}

// The bend of the mesh at its top, in degrees (render --bend): from -360 to 360, else 0.
function bendChoice(text) {
  const degrees = Number(text ?? 0);
  return Number.isFinite(degrees) && Math.abs(degrees) <= 360 ? degrees : 0;
}

// What is drawn behind the model: "map" (the environment map, where the page holds one),
// "sh" (the SH light) or "0" (nothing). Default and "1": the map where there is one.
function skyChoice(param) {
  if (param === "0" || param === "sh") return param;
  return DATA.light.map ? "map" : "sh";
}

function stateQuery(state) {
  const round = (v) => Number(v.toFixed(5));
  const c = state.camera;
  return `?cam=${[...c.eye, ...c.target, c.fov].map(round).join(",")}` +
    `&rot=${state.rotation.map(round).join(",")}&exposure=${round(state.exposure)}` +
    `&tone=${state.tone}&file=${state.file}&sky=${state.sky}` + sphereQuery(state, round) +
    (state.zonal ? "&zonal=1" : "") + (state.bend ? `&bend=${round(state.bend)}` : "");
}

function sphereQuery(state, round) {
  const sphere = activeSphere(state);
  if (state.sphere === "off") return "&sphere=0";
  if (!sphere) return "";
  return `&sphere=${[...sphere.centre, sphere.radius].map(round).join(",")}${state.fly ? "&fly=1" : ""}`;
}

// The sphere drawn for the current file: null where it has no probes or it is off.
function activeSphere(state) {
  const probes = DATA.bakes[state.file].probes;
  if (!probes || state.sphere === "off") return null;
  if (state.sphere === "default") return { centre: probes.sphereCentre, radius: probes.sphereRadius };
  return { centre: state.sphere.centre, radius: state.sphere.radius ?? probes.sphereRadius };
}

// ---- The camera: render::Camera's look-at and projection, in WebGL's clip space ----
// `up` (+Y) unless it is parallel to the view direction; then +Z, then +X (Camera::usable_up).
function usableUp(camera) {
  const forward = normalize(sub(camera.target, camera.eye));
  for (const up of [[0, 1, 0], [0, 0, 1], [1, 0, 0]]) {
    if (length(cross(forward, up)) > 1e-3) return up;
  }
  return [0, 1, 0];
}

function cameraBasis(camera) {
  const forward = normalize(sub(camera.target, camera.eye));
  const right = normalize(cross(forward, usableUp(camera)));
  const up = cross(right, forward);
  return { forward, right, up };
}

// The box of what is drawn: the file's mesh (`bounds`, bent as it is drawn) and the test
// sphere (render merges the two).
function drawnBounds(bounds, sphere) {
  if (!sphere) return bounds;
  const low = sphere.centre.map((c) => c - sphere.radius);
  const high = sphere.centre.map((c) => c + sphere.radius);
  return [bounds[0].map((v, a) => Math.min(v, low[a])), bounds[1].map((v, a) => Math.max(v, high[a]))];
}

// The bend of a file's mesh by `degrees` at its top, as bend.glsl and zonal::Bend take it.
function bendOf(bake, degrees) {
  return {
    angle: (degrees * Math.PI) / 180,
    origin: [0.5 * (bake.boundsMin[0] + bake.boundsMax[0]), bake.boundsMin[1], 0],
    height: bake.boundsMax[1] - bake.boundsMin[1],
  };
}

// Where `bend` puts a point (bend.glsl's bend()).
function bendPoint(bend, p) {
  if (bend.angle === 0 || bend.height <= 0) return p;
  const local = sub(p, bend.origin);
  const radius = bend.height / bend.angle;
  const turn = local[1] / radius;
  const arm = radius - local[0];
  return add(bend.origin, [radius - arm * Math.cos(turn), arm * Math.sin(turn), local[2]]);
}

// The bounds of a file's mesh bent by `degrees`.
function bentBounds(bake, positions, degrees) {
  if (!degrees) return [bake.boundsMin, bake.boundsMax];
  const bend = bendOf(bake, degrees);
  const low = [Infinity, Infinity, Infinity];
  const high = [-Infinity, -Infinity, -Infinity];
  for (let i = 0; i < positions.length; i += 3) {
    const p = bendPoint(bend, [positions[i], positions[i + 1], positions[i + 2]]);
    for (let a = 0; a < 3; a++) [low[a], high[a]] = [Math.min(low[a], p[a]), Math.max(high[a], p[a])];
  }
  return [low, high];
}

// Near and far planes hugging the bounding sphere of `[low, high]` (render's depth_range).
function depthRange(camera, [low, high]) {
  const center = scale(add(low, high), 0.5);
  const halfDiagonal = length(sub(high, low)) * 0.5;
  const floor = 1e-3 * Math.max(1, ...center.map(Math.abs));
  const radius = Number.isFinite(halfDiagonal) ? Math.max(halfDiagonal, floor) : 1;
  const distance = length(sub(center, camera.eye));
  const far = (distance + radius) * 1.01;
  const near = Math.max((distance - radius) * 0.99, far * 1e-4);
  return [near, far];
}

// Column-major clip-from-world: a right-handed look-at, then a perspective projection to
// WebGL's [-1, 1] depth (render uses [0, 1]; x and y are the same).
function clipFromWorld(camera, aspect, near, far) {
  const { forward, right, up } = cameraBasis(camera);
  const f = 1 / Math.tan((camera.fov * Math.PI) / 360);
  const view = [
    [...right, -dot(right, camera.eye)],
    [...up, -dot(up, camera.eye)],
    [...scale(forward, -1), dot(forward, camera.eye)],
    [0, 0, 0, 1],
  ];
  const projection = [
    [f / aspect, 0, 0, 0],
    [0, f, 0, 0],
    [0, 0, (far + near) / (near - far), (2 * far * near) / (near - far)],
    [0, 0, -1, 0],
  ];
  const out = new Float32Array(16);
  for (let row = 0; row < 4; row++) {
    for (let col = 0; col < 4; col++) {
      let sum = 0;
      for (let k = 0; k < 4; k++) sum += projection[row][k] * view[k][col];
      out[col * 4 + row] = sum;
    }
  }
  return out;
}

// ---- WebGL resources ----
function decodeBase64(text, ArrayType) {
  const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
  return new ArrayType(bytes.buffer);
}

function compile(gl, defines, parts) {
  const header = `#version 300 es\nprecision highp float;\nprecision highp int;\n${defines}\n`;
  const source = (ids) => header + ids.map((id) => document.getElementById(id).textContent).join("\n");
  const shader = (type, ids) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, source(ids));
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  };
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, parts.vertex));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, parts.fragment));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(program));
  return program;
}

// The transfer as a float texture: texel receiver * COEFFS + k holds coefficient k of every
// channel (the file stores each receiver's channels one after the other: channel-major).
// A receiver is a vertex, or a lightmap texel for a lightmapped file.
function transferTexture(gl, bake, stored, receivers) {
  return receiverTexture(gl, stored, receivers, bake.bands * bake.bands, bake.channels);
}

// `coeffs` values of `channels` channels per receiver (channel-major in `stored`) as a float
// texture: texel receiver * coeffs + k holds value k of every channel.
function receiverTexture(gl, stored, receivers, coeffs, channels) {
  const texels = receivers * coeffs;
  const height = Math.ceil(texels / TRANSFER_WIDTH);
  const data = new Float32Array(TRANSFER_WIDTH * height * channels);
  for (let r = 0; r < receivers; r++) {
    for (let c = 0; c < channels; c++) {
      const from = (r * channels + c) * coeffs;
      for (let k = 0; k < coeffs; k++) data[(r * coeffs + k) * channels + c] = stored[from + k];
    }
  }
  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  const [internal, format] = channels === 3 ? [gl.RGB32F, gl.RGB] : [gl.R32F, gl.RED];
  gl.texImage2D(gl.TEXTURE_2D, 0, internal, TRANSFER_WIDTH, height, 0, format, gl.FLOAT, data);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  return texture;
}

// The program, vertex arrays and transfer texture of one file: relit per vertex (mesh.vert),
// from its zonal transfer where `zonal` asks (zonal.glsl), or per texel of its lightmap
// (lightmap.vert, lightmap.frag).
function meshResources(gl, bake, zonal) {
  const lightmap = !zonal && bake.lightmap;
  const defines = `#define COEFFS ${bake.bands * bake.bands}\n#define CHANNELS ${bake.channels}\n` +
    `#define TRANSFER_WIDTH ${TRANSFER_WIDTH}` + (zonal ? `\n#define ZONAL_BANDS ${zonal.bands}` : "");
  const perVertex = zonal ? ["bend-function", "zonal-relight", "mesh-vertex"] : ["bend-function", "transfer", "mesh-vertex"];
  const program = lightmap
    ? compile(gl, defines, { vertex: ["bend-function", "lightmap-vertex"], fragment: ["tone-map", "transfer", "lightmap-fragment"] })
    : compile(gl, defines, { vertex: perVertex, fragment: ["tone-map", "mesh-fragment"] });
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const attribute = (name, values, size) => {
    const location = gl.getAttribLocation(program, name);
    if (location < 0 || values === null) return;
    gl.bindBuffer(gl.ARRAY_BUFFER, gl.createBuffer());
    gl.bufferData(gl.ARRAY_BUFFER, values, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
  };
  const positions = decodeBase64(bake.positions, Float32Array);
  attribute("position", positions, 3);
  attribute("albedo", bake.albedo ? decodeBase64(bake.albedo, Float32Array) : null, 3);
  if (zonal) attribute("axis", decodeBase64(zonal.axes, Float32Array), 3);
  if (lightmap) attribute("texcoord", decodeBase64(lightmap.texcoords, Float32Array), 2);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, gl.createBuffer());
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, decodeBase64(bake.indices, Uint32Array), gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  const texture = zonal
    ? receiverTexture(gl, decodeBase64(zonal.coeffs, Float32Array), bake.vertices, zonal.bands, zonal.channels)
    : lightmap
      ? transferTexture(gl, bake, decodeBase64(lightmap.transfer, Float32Array), lightmap.width * lightmap.height)
      : transferTexture(gl, bake, decodeBase64(bake.transfer, Float32Array), bake.vertices);
  const albedoLocation = gl.getAttribLocation(program, "albedo");
  return { program, vao, texture, albedoLocation, hasAlbedo: !!bake.albedo, positions, bounds: new Map() };
}

function uniforms(gl, program) {
  const cache = {};
  return (name) => (name in cache ? cache[name] : (cache[name] = gl.getUniformLocation(program, name)));
}

function setToneMap(gl, at, state) {
  gl.uniform1f(at("exposure_stops"), state.exposure);
  gl.uniform1i(at("tone_map_kind"), TONE_MAPS.indexOf(state.tone));
}

// The map's lat-long copy as a half-float texture, row 0 (the top, +Y) first: texture
// coordinate v runs down the map as light::mapping's rows do.
function skyMapTexture(gl, map) {
  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGB16F, map.width, map.height, 0, gl.RGB, gl.HALF_FLOAT,
    decodeBase64(map.rgb, Uint16Array));
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.REPEAT);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  return texture;
}

// ---- Drawing ----
class Viewer {
  constructor(canvas, state) {
    this.canvas = canvas;
    this.state = state;
    this.gl = canvas.getContext("webgl2", { antialias: false, preserveDrawingBuffer: true });
    if (!this.gl) throw new Error("this browser has no WebGL2");
    this.meshes = new Map();
    this.spheres = new Map();
    this.sky = null;
    this.skyMap = null;
  }

  // A file's drawing resources, relit from its zonal transfer where the state asks and it
  // has one.
  mesh(index) {
    const bake = DATA.bakes[index];
    const zonal = this.state.zonal && bake.zonal ? bake.zonal : null;
    const key = `${index}:${!!zonal}`;
    if (!this.meshes.has(key)) this.meshes.set(key, meshResources(this.gl, bake, zonal));
    return this.meshes.get(key);
  }

  // The bounds of the current file's mesh as drawn (bent).
  meshBounds() {
    const { state } = this;
    const mesh = this.mesh(state.file);
    if (!mesh.bounds.has(state.bend)) {
      mesh.bounds.set(state.bend, bentBounds(DATA.bakes[state.file], mesh.positions, state.bend));
    }
    return mesh.bounds.get(state.bend);
  }

  skyProgram() {
    if (!this.sky) {
      const program = compile(this.gl, `#define SH_BANDS ${DATA.light.bands}`,
        { vertex: ["sky-vertex"], fragment: ["tone-map", "sh-sum", "sky-fragment"] });
      this.sky = { program, at: uniforms(this.gl, program) };
    }
    return this.sky;
  }

  skyMapProgram() {
    if (!this.skyMap) {
      const program = compile(this.gl, "", { vertex: ["sky-vertex"], fragment: ["tone-map", "sky-map-fragment"] });
      const texture = skyMapTexture(this.gl, DATA.light.map);
      this.skyMap = { program, texture, at: uniforms(this.gl, program) };
    }
    return this.skyMap;
  }

  // The light as the page uses it: the file's light turned by state.rotation.
  light() {
    const key = this.state.rotation.join(",");
    if (this.lightKey !== key) {
      this.lightKey = key;
      this.rotatedLight = rotateLight(DATA.light.coeffs, DATA.light.bands, this.state.rotation);
    }
    return this.rotatedLight;
  }

  draw() {
    const { gl, canvas, state } = this;
    const width = Math.max(1, Math.round(canvas.clientWidth * devicePixelRatio));
    const height = Math.max(1, Math.round(canvas.clientHeight * devicePixelRatio));
    if (canvas.width !== width || canvas.height !== height) [canvas.width, canvas.height] = [width, height];
    gl.viewport(0, 0, width, height);
    gl.clearColor(0, 0, 0, 0);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    const light = this.light();
    if (state.sky === "map" && DATA.light.map) this.drawSkyMap(width, height);
    else if (state.sky !== "0") this.drawSky(light, width, height);
    const sphere = activeSphere(state);
    const clip = clipFromWorld(state.camera, width / height,
      ...depthRange(state.camera, drawnBounds(this.meshBounds(), sphere)));
    this.drawMesh(light, clip);
    this.drawSphere(light, clip, sphere);
  }

  sphereOf(index) {
    if (!this.spheres.has(index)) this.spheres.set(index, sphereResources(this.gl, DATA.bakes[index].probes));
    return this.spheres.get(index);
  }

  // The irradiance's SH at the current sphere's centre, or null (no sphere, or no valid probe
  // around it).
  sphereIrradiance(light) {
    const sphere = activeSphere(this.state);
    return sphere ? this.sphereOf(this.state.file).field.irradianceAt(sphere.centre, light) : null;
  }

  drawSphere(light, clip, sphere) {
    const message = document.getElementById("message");
    message.textContent = "";
    if (!sphere) return;
    const irradiance = this.sphereIrradiance(light);
    if (!irradiance) {
      message.textContent = "no valid probe lights the sphere here";
      return;
    }
    const { gl, state } = this;
    const { program, vao, at } = this.sphereOf(state.file);
    const toRadiance = DATA.sphere.albedo / Math.PI;
    gl.useProgram(program);
    gl.uniformMatrix4fv(at("clip_from_world"), false, clip);
    gl.uniform3fv(at("sh_coeffs"), irradiance.flat().map((e) => e * toRadiance));
    gl.uniform3fv(at("centre"), sphere.centre);
    gl.uniform1f(at("radius"), sphere.radius);
    setToneMap(gl, at, state);
    gl.enable(gl.DEPTH_TEST);
    gl.bindVertexArray(vao);
    gl.drawElements(gl.TRIANGLES, DATA.sphere.triangles * 3, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }

  drawSky(light, width, height) {
    const { gl } = this;
    const { program, at } = this.skyProgram();
    gl.useProgram(program);
    gl.uniform3fv(at("sh_coeffs"), light.flat());
    this.drawBackdrop(at, width, height);
  }

  // The map turned as the light is: first by the rotation it was written with, then by the
  // page's. The rows of R, read as GLSL's columns, give R's transpose: map from world.
  drawSkyMap(width, height) {
    const { gl, state } = this;
    const { program, texture, at } = this.skyMapProgram();
    const turn = matrixProduct(yawPitchRollMatrix(...state.rotation),
      yawPitchRollMatrix(...DATA.light.map.yawPitchRoll));
    gl.useProgram(program);
    gl.uniformMatrix3fv(at("map_from_world"), false, turn.flat());
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, texture);
    gl.uniform1i(at("sky_map"), 0);
    this.drawBackdrop(at, width, height);
  }

  // The screen-filling triangle of a sky, its view rays from the camera.
  drawBackdrop(at, width, height) {
    const { gl, state } = this;
    const { forward, right, up } = cameraBasis(state.camera);
    const tanHalf = Math.tan((state.camera.fov * Math.PI) / 360);
    gl.uniform3fv(at("camera_forward"), forward);
    gl.uniform3fv(at("camera_right"), right);
    gl.uniform3fv(at("camera_up"), up);
    gl.uniform2f(at("half_extent"), tanHalf * (width / height), tanHalf);
    gl.uniform2f(at("viewport_size"), width, height);
    setToneMap(gl, at, state);
    gl.disable(gl.DEPTH_TEST);
    gl.bindVertexArray(null);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
  }

  drawMesh(light, clip) {
    const { gl, state } = this;
    const bake = DATA.bakes[state.file];
    const mesh = this.mesh(state.file);
    const at = uniforms(gl, mesh.program);
    gl.useProgram(mesh.program);
    gl.uniformMatrix4fv(at("clip_from_world"), false, clip);
    gl.uniform3fv(at("light"), light.slice(0, bake.bands * bake.bands).flat());
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, mesh.texture);
    gl.uniform1i(at("transfer"), 0);
    gl.uniform1i(at("zonal"), 0);
    const bend = bendOf(bake, state.bend);
    gl.uniform1f(at("bend_angle"), bend.angle);
    gl.uniform3fv(at("bend_origin"), bend.origin);
    gl.uniform1f(at("bend_height"), bend.height);
    setToneMap(gl, at, state);
    if (!mesh.hasAlbedo && mesh.albedoLocation >= 0) gl.vertexAttrib3f(mesh.albedoLocation, 1, 1, 1);
    if (bake.lightmap) gl.uniform2i(at("lightmap_size"), bake.lightmap.width, bake.lightmap.height);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    gl.disable(gl.CULL_FACE); // both faces, as render draws them
    gl.bindVertexArray(mesh.vao);
    gl.drawElements(gl.TRIANGLES, bake.triangles * 3, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
  }
}

// ---- Input: mouse and controls change the state, which redraws and updates the URL ----
function orbit(camera, dAzimuth, dElevation) {
  const offset = sub(camera.eye, camera.target);
  const distance = length(offset);
  const elevation = Math.asin(Math.max(-1, Math.min(1, offset[1] / distance)));
  const azimuth = Math.atan2(offset[0], offset[2]);
  const limit = Math.PI / 2 - 1e-3;
  const e = Math.max(-limit, Math.min(limit, elevation + dElevation));
  const a = azimuth + dAzimuth;
  const direction = [Math.cos(e) * Math.sin(a), Math.sin(e), Math.cos(e) * Math.cos(a)];
  camera.eye = add(camera.target, scale(direction, distance));
}

function zoom(camera, factor) {
  camera.eye = add(camera.target, scale(sub(camera.eye, camera.target), factor));
}

// Moves the sphere in the plane facing the camera, following the pointer at its depth.
function moveSphere(state, dx, dy, canvasHeight) {
  const sphere = activeSphere(state);
  if (!sphere) return;
  const { forward, right, up } = cameraBasis(state.camera);
  const depth = dot(sub(sphere.centre, state.camera.eye), forward);
  const perPixel = (2 * depth * Math.tan((state.camera.fov * Math.PI) / 360)) / canvasHeight;
  const centre = add(sphere.centre, add(scale(right, dx * perPixel), scale(up, -dy * perPixel)));
  state.sphere = { centre, radius: sphere.radius };
}

function connectInput(viewer, redraw) {
  const { canvas, state } = viewer;
  let last = null;
  canvas.addEventListener("contextmenu", (e) => e.preventDefault());
  canvas.addEventListener("pointerdown", (e) => {
    const sphere = e.altKey || e.button === 1;
    last = { x: e.clientX, y: e.clientY, light: !sphere && (e.shiftKey || e.button === 2), sphere };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointerup", () => { last = null; });
  canvas.addEventListener("pointermove", (e) => {
    if (!last) return;
    const [dx, dy] = [e.clientX - last.x, e.clientY - last.y];
    [last.x, last.y] = [e.clientX, e.clientY];
    if (last.sphere) {
      state.fly = false;
      moveSphere(state, dx, dy, canvas.clientHeight);
    } else if (last.light) {
      state.rotation[0] += dx * 0.5; // yaw about +Y
      state.rotation[1] += dy * 0.5; // pitch about +X
    } else {
      orbit(state.camera, -dx * 0.01, dy * 0.01);
    }
    redraw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    zoom(state.camera, Math.exp(e.deltaY * 0.001));
    redraw();
  }, { passive: false });
  const fileSelect = document.getElementById("file");
  DATA.bakes.forEach((bake, i) => fileSelect.add(new Option(`${i + 1}: ${bake.name} (${bake.mode}, ${bake.bands} bands${bake.probes ? ", probes" : ""}${bake.zonal ? ", zonal" : ""})`, i)));
  const exposure = document.getElementById("exposure");
  const tone = document.getElementById("tone");
  const sky = document.getElementById("sky");
  const sphere = document.getElementById("sphere");
  const fly = document.getElementById("fly");
  const zonal = document.getElementById("zonal");
  const bend = document.getElementById("bend");
  const show = () => {
    document.getElementById("zonal-control").hidden = !DATA.bakes[state.file].zonal;
    zonal.checked = state.zonal;
    bend.value = state.bend;
    document.getElementById("bend-value").textContent = state.bend.toFixed(0);
    document.getElementById("probe-controls").hidden = !DATA.bakes[state.file].probes;
    sphere.checked = state.sphere !== "off";
    fly.checked = state.fly;
    fileSelect.value = state.file;
    exposure.value = state.exposure;
    document.getElementById("exposure-value").textContent = state.exposure.toFixed(1);
    tone.value = state.tone;
    sky.value = state.sky;
  };
  fileSelect.addEventListener("change", () => { state.file = Number(fileSelect.value); redraw(); });
  exposure.addEventListener("input", () => { state.exposure = Number(exposure.value); redraw(); });
  tone.addEventListener("change", () => { state.tone = tone.value; redraw(); });
  if (!DATA.light.map) sky.querySelector('option[value="map"]').remove();
  sky.addEventListener("change", () => { state.sky = sky.value; redraw(); });
  sphere.addEventListener("change", () => { state.sphere = sphere.checked ? "default" : "off"; redraw(); });
  fly.addEventListener("change", () => { state.fly = fly.checked; redraw(); });
  zonal.addEventListener("change", () => { state.zonal = zonal.checked; redraw(); });
  bend.addEventListener("input", () => { state.bend = Number(bend.value); redraw(); });
  window.addEventListener("keydown", (e) => {
    const index = Number(e.key) - 1;
    if (index >= 0 && index < DATA.bakes.length) { state.file = index; redraw(); }
  });
  window.addEventListener("resize", redraw);
  return show;
}

// ---- Reports for tests and measurements, as JSON in #report ----
function report(value) {
  const element = document.getElementById("report");
  element.textContent = JSON.stringify(value);
}

// Frame time: `frames` draws, each waited for by reading one pixel back (so the time is the
// GPU's work too, not only the queueing of commands).
function bench(viewer, frames) {
  const gl = viewer.gl;
  const pixel = new Uint8Array(4);
  viewer.draw();
  gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
  const start = performance.now();
  const flying = !!activeSphere(viewer.state);
  for (let i = 0; i < frames; i++) {
    viewer.state.rotation[0] += 360 / frames; // a new light every frame, as when dragging
    if (flying) flySphere(viewer, i / 30); // and the sphere's probes looked up again
    viewer.draw();
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
  }
  const elapsed = performance.now() - start;
  const bake = DATA.bakes[viewer.state.file];
  return {
    frames,
    ms_per_frame: elapsed / frames,
    width: viewer.canvas.width,
    height: viewer.canvas.height,
    vertices: bake.vertices,
    triangles: bake.triangles,
    bands: bake.bands,
    probe_sphere: flying,
    renderer: gl.getParameter(gl.RENDERER),
  };
}

function main() {
  const params = new URLSearchParams(location.search);
  const state = initialState(params);
  if (params.get("ui") === "0") document.getElementById("controls").hidden = true;
  const viewer = new Viewer(document.getElementById("view"), state);
  let show = () => {};
  let pending = false;
  const redraw = () => {
    if (pending) return;
    pending = true;
    requestAnimationFrame(() => {
      pending = false;
      viewer.draw();
      show();
      document.getElementById("url").textContent = stateQuery(state);
      // Not every frame of a flight: browsers throttle pages that rewrite their URL so often.
      if (!state.fly) history.replaceState(null, "", stateQuery(state));
    });
  };
  show = connectInput(viewer, redraw);
  const flightStart = performance.now();
  const fly = () => {
    if (state.fly && flySphere(viewer, (performance.now() - flightStart) / 1000)) redraw();
    requestAnimationFrame(fly);
  };
  requestAnimationFrame(fly);
  // The first frame is drawn at once, so a headless screenshot taken at load sees it.
  viewer.draw();
  show();
  document.getElementById("url").textContent = stateQuery(state);
  const frames = Number(params.get("bench"));
  if (frames > 0) report(bench(viewer, frames));
  if (params.get("report") === "light") report({ bands: DATA.light.bands, coeffs: viewer.light() });
  if (params.get("report") === "sphere") {
    report({ sphere: activeSphere(state), irradiance: viewer.sphereIrradiance(viewer.light()) });
  }
}

// Moves the current file's sphere to where its flight is at `seconds`; false without one.
function flySphere(viewer, seconds) {
  const sphere = activeSphere(viewer.state);
  if (!sphere) return false;
  const centre = viewer.sphereOf(viewer.state.file).field.flightAt(seconds);
  viewer.state.sphere = { centre, radius: sphere.radius };
  return true;
}

try {
  main();
} catch (error) {
  document.getElementById("message").textContent = `prt-gpu view: ${error.message}`;
  report({ error: String(error.message) });
  throw error;
}
