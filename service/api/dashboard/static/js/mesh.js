// The deformed surface mesh of one frame, from the voxel centres: sim/mesh.py's
// deformed_mesh (voxel_axes, voxel_corners, mesh_vertices) in JavaScript, for the replay.
// The mesh's topology (meshVert, meshFace) comes with the frames (service/api/frames.py).
// A vertex is the mean, over the voxels sharing that lattice corner, of each voxel's corner:
// its centre plus its axes times (+-1/2); a voxel's axes are estimated from its neighbours'
// centres (half the vector between the two neighbours along an axis, or the vector to the
// one there; an axis without neighbours perpendicular to the others, one voxel long).
// Arrays are flat: positions V*3, axes V*9 (axes[9 v + 3 a + x]: axis a's component x).

/** Neighbour of each voxel on -x, +x, -y, +y, -z, +z (-1: none), Int32Array(V*6). */
export function neighbours(lattice, voxelCount) {
  const key = (i, j, k) => `${i},${j},${k}`;
  const index = new Map();
  for (let v = 0; v < voxelCount; v++) index.set(key(lattice[3 * v], lattice[3 * v + 1], lattice[3 * v + 2]), v);
  const nbr = new Int32Array(6 * voxelCount);
  for (let v = 0; v < voxelCount; v++) {
    for (let f = 0; f < 6; f++) {
      const cell = [lattice[3 * v], lattice[3 * v + 1], lattice[3 * v + 2]];
      cell[f >> 1] += f & 1 ? 1 : -1;
      nbr[6 * v + f] = index.get(key(...cell)) ?? -1;
    }
  }
  return nbr;
}

function unit(vector) {
  const length = Math.hypot(vector[0], vector[1], vector[2]) || 1e-300;
  return vector.map((x) => x / length);
}

function cross(a, b) {
  return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
}

/** One voxel's three axes (arrays of 3, metres) from `positions` (V*3). */
function axesOf(v, positions, nbr, size) {
  const at = (u) => [positions[3 * u], positions[3 * u + 1], positions[3 * u + 2]];
  const centre = at(v);
  const axes = [null, null, null];
  const known = [];
  for (let a = 0; a < 3; a++) {
    const low = nbr[6 * v + 2 * a], high = nbr[6 * v + 2 * a + 1];
    if (low >= 0 && high >= 0) axes[a] = at(high).map((x, c) => (x - at(low)[c]) / 2);
    else if (high >= 0) axes[a] = at(high).map((x, c) => x - centre[c]);
    else if (low >= 0) axes[a] = centre.map((x, c) => x - at(low)[c]);
    if (axes[a]) known.push(a);
  }
  const scaled = (vector) => unit(vector).map((x) => size * x);
  if (known.length === 0) return [[size, 0, 0], [0, size, 0], [0, 0, size]];
  if (known.length === 1) {
    const a = known[0], b = (a + 1) % 3, c = (a + 2) % 3;
    const u = unit(axes[a]);
    const rest = (axis) => [0, 1, 2].map((x) => (x === axis ? 1 : 0) - u[axis] * u[x]);
    const axisB = Math.abs(u[b]) <= Math.sqrt(0.75) ? unit(rest(b)) : unit(cross(unit(rest(c)), u));
    axes[b] = scaled(axisB);
    axes[c] = scaled(cross(u, axisB));
  } else if (known.length === 2) {
    const a = [0, 1, 2].find((x) => !known.includes(x));
    axes[a] = scaled(cross(axes[(a + 1) % 3], axes[(a + 2) % 3]));
  }
  return axes;
}

/** Every voxel's axes into `out` (Float32Array V*9). */
export function voxelAxes(positions, nbr, size, voxelCount, out) {
  for (let v = 0; v < voxelCount; v++) {
    const axes = axesOf(v, positions, nbr, size);
    for (let a = 0; a < 3; a++) for (let x = 0; x < 3; x++) out[9 * v + 3 * a + x] = axes[a][x];
  }
  return out;
}

/** Vertex positions into `out` (Float32Array M*3): the mean of the shared corners. */
export function meshVertices(meshVert, positions, axes, out) {
  const vertexCount = meshVert.length / 8;
  for (let k = 0; k < vertexCount; k++) {
    let x = 0, y = 0, z = 0, count = 0;
    for (let slot = 0; slot < 8; slot++) {
      const code = meshVert[8 * k + slot];
      if (code < 0) break;
      const v = code >> 3, c = code & 7;
      const sx = ((c >> 2) & 1) - 0.5, sy = ((c >> 1) & 1) - 0.5, sz = (c & 1) - 0.5;
      for (let d = 0; d < 3; d++) {
        const value = positions[3 * v + d] + sx * axes[9 * v + d] + sy * axes[9 * v + 3 + d] + sz * axes[9 * v + 6 + d];
        if (d === 0) x += value; else if (d === 1) y += value; else z += value;
      }
      count += 1;
    }
    out[3 * k] = x / count;
    out[3 * k + 1] = y / count;
    out[3 * k + 2] = z / count;
  }
  return out;
}
