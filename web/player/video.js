// Texture images of a textured stream for the player. (Placeholder until the texture video
// path lands: streams play untextured.)

export class TexturePlayer {
  constructor(stream, infos) {
    this.textured = infos.some((f) => f.textureBytes > 0);
    this.note = this.textured ? 'texture not shown' : '';
  }
  async image() {
    return null;
  }
}
