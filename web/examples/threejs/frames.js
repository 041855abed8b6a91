// The three.js example's decoding, which needs no three.js (web/test/example.test.js runs it
// in Node): a dynmesh stream's frames as flat arrays for a BufferGeometry, and the texture
// images of a textured stream.
//
// `new MeshFrames(bytes)`: `count` frames; `frame(i)` (in order: a texture group's UVs are
// read when its first frame is decoded) gives {positions: Float32Array xyz, index:
// Uint32Array triangles or null, uvs: Float32Array or null}. A textured frame has one vertex
// per face corner (a UV seam splits a vertex; a geometry has one index) and no index, its v
// measured down from the image's top row as ImageData rows go. `await image(i)` is frame i's
// texture (ImageData, decoded with WebCodecs) or null; `textureNote` says why none.

import { Decoder } from '../../src/index.js';
import { frameUvs } from '../../src/texture/unit.js';
import { TexturePlayer } from '../../player/video.js';

export class MeshFrames {
  /** @param {Uint8Array} bytes a whole stream */
  constructor(bytes) {
    this.decoder = new Decoder(bytes);
    this.count = this.decoder.frameCount;
    this.uvs = frameUvs(this.decoder);
    this.textures = new TexturePlayer();
    for (let i = 0; i < this.count; i++) {
      const payload = this.decoder.texturePayload(i);
      if (payload !== null) this.textures.add(i, payload);
    }
    this.textureNote = this.textures.note;
  }

  frame(i) {
    const { positions, faces } = this.decoder.decodeFrame(i);
    const uv = this.uvs(i);
    if (!uv) return { positions: Float32Array.from(positions), index: faces, uvs: null };
    const m = faces.length;
    const out = new Float32Array(3 * m), uvs = new Float32Array(2 * m);
    for (let c = 0; c < m; c++) {
      const v = faces[c], t = uv.uvFaces[c];
      out.set(positions.subarray(3 * v, 3 * v + 3), 3 * c);
      uvs[2 * c] = uv.uv[2 * t];
      uvs[2 * c + 1] = 1 - uv.uv[2 * t + 1];
    }
    return { positions: out, index: null, uvs };
  }

  image(i) {
    return this.textures.image(i);
  }
}
