// Texture data of a textured stream for the player: the frame's UVs, from the texture units.
// (Placeholder until the UV atlas decoder lands: untextured rendering.)

/** A function giving frame i's {uv, uvFaces} (decoded after frame i), or null. */
export function frameUvs(dec) {
  return () => null;
}
