// Local frames of the subdivided mesh and displacements to world axes
// (`core/src/residual/displace.rs::local_frames` and `to_world`, over
// `geom::mesh::vertex_normals`; docs/bitstream.md sections 8.5 and 8.6).
//
// Contract: `vertexNormals` and `frameToWorld` give the Rust normals and world displacements
// bit for bit, each expression in the Rust operation order.

/** Area-weighted unit vertex normals, zero where there is none (`mesh::vertex_normals`). */
export function vertexNormals(p, faces) {
  const acc = new Float64Array(p.length);
  for (let f = 0; f < faces.length; f += 3) {
    const a = 3 * faces[f], b = 3 * faces[f + 1], c = 3 * faces[f + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    acc[a] += nx; acc[a + 1] += ny; acc[a + 2] += nz;
    acc[b] += nx; acc[b + 1] += ny; acc[b + 2] += nz;
    acc[c] += nx; acc[c + 1] += ny; acc[c + 2] += nz;
  }
  for (let i = 0; i < acc.length; i += 3) {
    const n = Math.sqrt(acc[i] * acc[i] + acc[i + 1] * acc[i + 1] + acc[i + 2] * acc[i + 2]);
    if (n > 1e-300) {
      const s = 1.0 / n;
      acc[i] *= s; acc[i + 1] *= s; acc[i + 2] *= s;
    } else {
      acc[i] = 0; acc[i + 1] = 0; acc[i + 2] = 0;
    }
  }
  return acc;
}

/**
 * World displacement of one vertex from local (n, t, b) components `c`, for its unit normal
 * `n` (`displace::frame_from_normal` and `to_world`). Writes into `out` at `o`.
 */
export function frameToWorld(nx, ny, nz, c0, c1, c2, out, o) {
  if (nx === 0 && ny === 0 && nz === 0) { nx = 0; ny = 0; nz = 1; }
  // The least aligned axis, the lowest on ties (the Rust fold over k = 1, 2).
  const ax = Math.abs(nx), ay = Math.abs(ny), az = Math.abs(nz);
  let axis = ay < ax ? 1 : 0;
  if (az < (axis === 0 ? ax : ay)) axis = 2;
  const na = axis === 0 ? nx : axis === 1 ? ny : nz;
  let tx = (axis === 0 ? 1 : 0) - nx * na, ty = (axis === 1 ? 1 : 0) - ny * na, tz = (axis === 2 ? 1 : 0) - nz * na;
  const len = Math.sqrt(tx * tx + ty * ty + tz * tz);
  if (len > 1e-300) {
    const s = 1.0 / len;
    tx *= s; ty *= s; tz *= s;
  } else {
    tx = 0; ty = 0; tz = 0;
  }
  const bx = ny * tz - nz * ty, by = nz * tx - nx * tz, bz = nx * ty - ny * tx;
  out[o] = nx * c0 + tx * c1 + bx * c2;
  out[o + 1] = ny * c0 + ty * c1 + by * c2;
  out[o + 2] = nz * c0 + tz * c1 + bz * c2;
}
