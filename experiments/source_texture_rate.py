"""What a capture's own texture costs through our video path: the first frame's source
texture coded as a one-picture video at several texture QPs and measured on the source mesh
itself (geometry lossless, UVs the source's), beside the test model's all-intra texture bytes
per frame and Y for the same capture. A floor for the texture stage: re-atlasing can only
lose detail, so when the test model's texture costs less than the source's own at the same Y,
the gap lies in what its texture images hold, not in our atlas or transfer.

    python experiments/source_texture_rate.py [liam_textured] [22,29,35,41]
"""

from __future__ import annotations

import csv
import sys

import dynmesh
from dynmesh.io import image_of
from dynmesh import api
from dynmesh.mesh import Mesh
from dynmesh.texture import video

import texture_qp_hull as hull



def main() -> int:
    seq = sys.argv[1] if len(sys.argv) > 1 else "liam_textured"
    qps = [int(q) for q in (sys.argv[2] if len(sys.argv) > 2 else "22,29,35,41").split(",")]
    source = dynmesh.read_mesh(sorted((hull.SHARED / "data" / seq).glob("*.obj"))[0])
    image = image_of(source)
    print(f"{seq}, frame 0's source texture ({image.shape[1]} x {image.shape[0]}) on its own mesh:")
    for codec in ("hevc", "av1"):
        for qp in qps:
            data = video.encode_video([image], codec, qp)
            decoded = Mesh(source.positions, source.faces, uvs=source.uvs, uv_faces=source.uv_faces,
                           image=next(video.decode_video(data, codec)))
            y = api.metrics(source, decoded, peak=hull.SEQUENCES[seq][2])["y_psnr"]
            print(f"  {codec} texture QP {qp}: {len(data)} bytes, Y {y:.2f} dB")
    with open(hull.SHARED / "anchors" / "tm14_textured_anchor.csv") as f:
        for r in csv.DictReader(f):
            if r["seq"] == seq and r["cond"] == "AI":
                print(f"  test model AI {r['rate']}: {int(r['tex_bytes']) / int(r['frames']):.0f} texture bytes per frame, Y {float(r['y']):.2f} dB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
