// Decoder of GET /individuals/{id}/frames (service.api.frames): a 24-byte header "SVXF",
// version, F frames, V voxels, M mesh vertices, T mesh triangles; then little-endian float32
// t[F], voxels[V][4] (i, j, k, material: 1 passive, 2 active), positions[F][V][3] (voxel
// centres, metres); then int32 meshVert[M][8] (8 voxel + corner of each voxel sharing the
// vertex, -1 pads) and meshFace[T][4] (3 vertices, counter-clockwise from outside; voxel).

const MAGIC = "SVXF";
const VERSION = 2;
const HEADER_BYTES = 24;

export class FramesError extends Error {}

/** {t: Float32Array(F), lattice: Int32Array(V*3), material: Uint8Array(V),
 *  positions: Float32Array(F*V*3), meshVert: Int32Array(M*8), meshFace: Int32Array(T*4),
 *  frameCount: F, voxelCount: V} of an ArrayBuffer. */
export function decodeFrames(buffer) {
  if (buffer.byteLength < HEADER_BYTES) throw new FramesError("frames: shorter than the header");
  const view = new DataView(buffer);
  const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
  const version = view.getUint32(4, true);
  if (magic !== MAGIC || version !== VERSION) {
    throw new FramesError(`frames: not a softevo frames file (magic ${magic}, version ${version})`);
  }
  const frameCount = view.getUint32(8, true);
  const voxelCount = view.getUint32(12, true);
  const vertexCount = view.getUint32(16, true);
  const triangleCount = view.getUint32(20, true);
  const floats = frameCount + 4 * voxelCount + 3 * frameCount * voxelCount;
  const ints = 8 * vertexCount + 4 * triangleCount;
  if (buffer.byteLength !== HEADER_BYTES + 4 * (floats + ints)) {
    throw new FramesError(`frames: ${buffer.byteLength} bytes, expected ${HEADER_BYTES + 4 * (floats + ints)}`);
  }
  const mesh = littleEndianInts(buffer, HEADER_BYTES + 4 * floats, ints);
  const values = littleEndianFloats(buffer, HEADER_BYTES, floats);
  const voxels = values.subarray(frameCount, frameCount + 4 * voxelCount);
  const lattice = new Int32Array(3 * voxelCount);
  const material = new Uint8Array(voxelCount);
  for (let v = 0; v < voxelCount; v++) {
    lattice[3 * v] = voxels[4 * v];
    lattice[3 * v + 1] = voxels[4 * v + 1];
    lattice[3 * v + 2] = voxels[4 * v + 2];
    material[v] = voxels[4 * v + 3];
  }
  return {
    t: values.subarray(0, frameCount),
    lattice,
    material,
    positions: values.subarray(frameCount + 4 * voxelCount),
    meshVert: mesh.subarray(0, 8 * vertexCount),
    meshFace: mesh.subarray(8 * vertexCount),
    frameCount,
    voxelCount,
  };
}

const HOST_IS_LITTLE_ENDIAN = new Uint8Array(new Uint16Array([1]).buffer)[0] === 1;

function littleEndianFloats(buffer, offset, count) {
  if (HOST_IS_LITTLE_ENDIAN) return new Float32Array(buffer, offset, count);
  const view = new DataView(buffer, offset, 4 * count);
  return Float32Array.from({ length: count }, (_, i) => view.getFloat32(4 * i, true));
}

function littleEndianInts(buffer, offset, count) {
  if (HOST_IS_LITTLE_ENDIAN) return new Int32Array(buffer, offset, count);
  const view = new DataView(buffer, offset, 4 * count);
  return Int32Array.from({ length: count }, (_, i) => view.getInt32(4 * i, true));
}
