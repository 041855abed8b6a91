//! Python bindings: numpy arrays in and out of the core and of `dynmesh_meshio` (OBJ and PLY
//! text, PNG, decoding a stream to files).
//!
//! Every function releases the GIL while the core works, so Python threads can encode
//! frames side by side.

mod colour;
mod decode_files;
mod errors;
mod image;
mod meshio;
mod options;
mod transfer;
mod uv;
use std::ffi::CString;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use dynmesh::decode;
use dynmesh::encode::{FrameStats, SequenceEncoder, TextureCost, MAX_REFERENCES};
use dynmesh::eval::{metrics, sampling};
use dynmesh::bitstream::{self, FrameType, SequenceHeader};
use dynmesh::texturing::{self, TexturePayload, MAX_SIDE, MIN_SIDE, TEXTURE_CODECS};
use dynmesh::Mesh;

use errors::{core_error, guarded, input_error, released};

pub(crate) fn positions_of(a: &PyReadonlyArray2<f64>) -> PyResult<Vec<[f64; 3]>> {
    let v = a.as_array();
    if v.ncols() != 3 {
        return Err(input_error("positions must have shape (N, 3)"));
    }
    Ok(v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

pub(crate) fn faces_of(a: &PyReadonlyArray2<i64>, vertex_count: usize) -> PyResult<Vec<[u32; 3]>> {
    let v = a.as_array();
    if v.ncols() != 3 {
        return Err(input_error("faces must have shape (M, 3)"));
    }
    let mut out = Vec::with_capacity(v.nrows());
    for (i, r) in v.rows().into_iter().enumerate() {
        let f = [r[0], r[1], r[2]];
        if f.iter().any(|&x| x < 0 || x as u64 >= vertex_count as u64) {
            return Err(input_error(format!("face {i} refers to a vertex that does not exist (there are {vertex_count}, numbered from 0)")));
        }
        out.push(f.map(|x| x as u32));
    }
    Ok(out)
}

fn mesh_of(positions: &PyReadonlyArray2<f64>, faces: &PyReadonlyArray2<i64>) -> PyResult<Mesh> {
    let p = positions_of(positions)?;
    let f = faces_of(faces, p.len())?;
    Ok(Mesh::new(p, f))
}

type MeshArrays<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>);

fn arrays_of<'py>(py: Python<'py>, m: Mesh) -> MeshArrays<'py> {
    let n = m.positions.len();
    let p = Array2::from_shape_vec((n, 3), m.positions.into_flattened()).expect("shape");
    let nf = m.faces.len();
    let f = Array2::from_shape_vec((nf, 3), m.faces.into_iter().flatten().map(i64::from).collect()).expect("shape");
    (p.into_pyarray(py), f.into_pyarray(py))
}


fn frame_type_name(t: Option<FrameType>) -> &'static str {
    match t {
        Some(FrameType::Intra) => "I",
        Some(FrameType::Predicted) => "P",
        None => "?",
    }
}

fn stats_dict<'py>(py: Python<'py>, s: &FrameStats) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("type", frame_type_name(s.frame_type))?;
    d.set_item("same_topology", s.same_topology)?;
    d.set_item("starts_texture_group", s.starts_texture_group)?;
    d.set_item("reference_distance", s.reference_distance)?;
    d.set_item("rejected_bytes", s.rejected_bytes)?;
    d.set_item("anchor_seconds", s.anchor_seconds)?;
    d.set_item("bytes", s.bytes)?;
    d.set_item("base_bytes", s.base_bytes)?;
    d.set_item("refreshed_faces", s.refreshed_faces)?;
    d.set_item("displacement_bytes", s.displacement_bytes)?;
    d.set_item("base_vertices", s.base_vertices)?;
    d.set_item("base_faces", s.base_faces)?;
    d.set_item("output_vertices", s.output_vertices)?;
    d.set_item("output_faces", s.output_faces)?;
    d.set_item("dropped_faces", s.dropped_faces)?;
    d.set_item("seconds", s.seconds)?;
    Ok(d)
}

fn header_dict<'py>(py: Python<'py>, h: &SequenceHeader) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("frame_count", h.frame_count)?;
    d.set_item("origin", h.grid.origin.to_vec())?;
    d.set_item("step", h.grid.step)?;
    d.set_item("bits", h.grid.bits)?;
    d.set_item("base_bits", h.base_bits)?;
    d.set_item("subdiv_iterations", h.subdiv_iterations())?;
    d.set_item("schemes", h.schemes.iter().map(|s| s.name()).collect::<Vec<_>>())?;
    d.set_item("components", h.components)?;
    d.set_item("aq", h.aq.is_some())?;
    if let Some(aq) = h.aq {
        d.set_item("aq_alpha", aq.alpha)?;
        d.set_item("aq_delta", aq.delta)?;
        d.set_item("aq_h", aq.h)?;
    }
    Ok(d)
}

/// A frame that loses at least 1/this of its faces for having no area or repeating another
/// face gets a warning (their number is in every frame's stats as `dropped_faces`). Captures
/// lose a few faces to welding at texture seams (liam: 1.6 %), which is no news to a user; a
/// mesh that is largely degenerate is.
const DROPPED_SHARE_WARNED: usize = 10;

/// Encodes the frames of one sequence in order; create it with the sequence's bounding box.
#[pyclass(module = "dynmesh._core")]
struct Encoder {
    inner: SequenceEncoder,
    /// Why the encoder codes no more frames: a frame failed after its coding had begun, so
    /// its state may hold a frame the caller never received.
    stopped: Option<String>,
}

#[pymethods]
impl Encoder {
    #[new]
    fn new(frame_count: u32, box_min: [f64; 3], box_max: [f64; 3], options: &Bound<'_, PyDict>) -> PyResult<Self> {
        let config = options::config_of(options)?;
        let inner = guarded(|| SequenceEncoder::new(config, frame_count, box_min, box_max))?.map_err(core_error)?;
        Ok(Self { inner, stopped: None })
    }

    /// Makes the next frame frame `index`, which must start a group (a multiple of the
    /// intra period): its frames then get the units the sequential encoder gives them.
    fn start_group(&mut self, index: u32) -> PyResult<()> {
        guarded(|| self.inner.start_group(index))?.map_err(core_error)
    }

    /// The serialized sequence header.
    fn header_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        Ok(PyBytes::new(py, &guarded(|| bitstream::write_header(self.inner.header()))?))
    }

    /// Encodes the next frame; returns (unit bytes, stats dict, (positions, faces) of the
    /// reconstruction, (positions, faces) of the decoded base mesh). `texture_cost` makes the
    /// decision weigh the bytes the frame's texture adds: `(continued, restarted)`, for a
    /// frame that keeps its texture group's atlas and for one that starts a group, or a
    /// callable that returns them (or None), called once the predicted candidate is built
    /// (`SequenceEncoder::encode_textured`); None: geometry alone. Raises InputError for a
    /// mesh the encoder refuses (the encoder is then as before the call). After an
    /// InternalError, or an error raised by `texture_cost`, the frame may be half coded: every
    /// later call raises InputError saying where the encoder stopped.
    #[pyo3(signature = (positions, faces, texture_cost=None))]
    #[allow(clippy::type_complexity)]
    fn encode_frame<'py>(
        &mut self,
        py: Python<'py>,
        positions: PyReadonlyArray2<'py, f64>,
        faces: PyReadonlyArray2<'py, i64>,
        texture_cost: Option<Bound<'py, PyAny>>,
    ) -> PyResult<(Bound<'py, PyBytes>, Bound<'py, PyDict>, MeshArrays<'py>, MeshArrays<'py>)> {
        if let Some(why) = &self.stopped {
            return Err(input_error(format!("this encoder stopped at {why}; it codes no more frames")));
        }
        let mesh = mesh_of(&positions, &faces)?;
        let frame = self.inner.next_frame();
        let inner = &mut self.inner;
        let texture_cost = texture_cost.map(Bound::unbind);
        let mut failed = None;
        let out = released(py, || {
            inner.encode_textured(&mesh, || {
                let cost = Python::with_gil(|py| texture_cost_of(texture_cost.as_ref().map(|c| c.bind(py))));
                cost.unwrap_or_else(|e| {
                    failed = Some(e);
                    None
                })
            })
        });
        let out = match (out, failed) {
            (Ok(out), None) => out,
            (Err(e), _) => {
                self.stopped = Some(format!("frame {frame} after an internal error"));
                return Err(e);
            }
            (Ok(_), Some(e)) => {
                self.stopped = Some(format!("frame {frame}, whose texture cost raised an error"));
                return Err(e);
            }
        };
        let out = out.map_err(core_error)?;
        let dropped = out.stats.dropped_faces;
        if dropped > 0 && dropped >= mesh.faces.len() / DROPPED_SHARE_WARNED {
            let message = format!(
                "frame {frame}: {dropped} of its {} faces have no area (corners that coincide or lie on one line) or repeat \
                 another face; they were left out of the coded surface",
                mesh.faces.len()
            );
            PyErr::warn(py, py.get_type::<PyUserWarning>().as_any(), &CString::new(message)?, 1)?;
        }
        let unit = PyBytes::new(py, &out.unit);
        Ok((unit, stats_dict(py, &out.stats)?, arrays_of(py, out.reconstruction), arrays_of(py, out.base)))
    }
}

/// The texture cost that `cost` stands for: None, `(continued, restarted)`, or a callable
/// that returns either.
fn texture_cost_of(cost: Option<&Bound<'_, PyAny>>) -> PyResult<Option<TextureCost>> {
    let Some(cost) = cost else { return Ok(None) };
    let value = if cost.is_callable() { cost.call0()? } else { cost.clone() };
    let Some((continued, restarted)) = value.extract::<Option<(f64, f64)>>()? else { return Ok(None) };
    if !(continued.is_finite() && restarted.is_finite() && continued >= 0.0 && restarted >= 0.0) {
        return Err(input_error("texture costs must be finite numbers of bytes, at least 0"));
    }
    Ok(Some(TextureCost { continued, restarted }))
}

/// The core decoder of `data` (see [`Decoder::new`]), decoding `lod` iterations if given.
pub(crate) fn open_decoder(data: &[u8], tolerant: bool, lod: Option<u32>) -> PyResult<decode::Decoder> {
    let open = if tolerant { decode::Decoder::new_tolerant } else { decode::Decoder::new };
    let mut inner = guarded(|| open(data.to_vec()))?.map_err(core_error)?;
    if let Some(lod) = lod {
        inner.set_lod(lod).map_err(core_error)?;
    }
    Ok(inner)
}

/// A parsed stream whose frames can be decoded in any order.
#[pyclass(module = "dynmesh._core")]
struct Decoder {
    inner: decode::Decoder,
}

#[pymethods]
impl Decoder {
    /// `tolerant`: open a stream with damaged frame units (only the header must be intact);
    /// `damage()` lists them and decoding a frame that depends on one fails. Raises
    /// DecodeError for a stream that cannot be opened, UnsupportedError for one of another
    /// format version, InputError for a `lod` beyond the stream's.
    #[new]
    #[pyo3(signature = (data, tolerant=false, lod=None))]
    fn new(data: &[u8], tolerant: bool, lod: Option<u32>) -> PyResult<Self> {
        Ok(Self { inner: open_decoder(data, tolerant, lod)? })
    }

    /// The damaged frame units: [(frame, start offset, end offset, reason)].
    fn damage(&self) -> Vec<(u32, u64, u64, String)> {
        self.inner.damage().into_iter().map(|(f, d)| (f, d.start, d.end, d.reason.clone())).collect()
    }

    /// Subdivision iterations decoded (the level of detail).
    #[getter]
    fn lod(&self) -> u32 {
        self.inner.lod()
    }

    #[getter]
    fn frame_count(&self) -> u32 {
        self.inner.frame_count()
    }

    /// Sequence header fields.
    fn header<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        header_dict(py, self.inner.header())
    }

    /// Per frame: type, reference, QP and byte sizes of the unit and its parts.
    fn frame_info<'py>(&self, py: Python<'py>, index: u32) -> PyResult<Bound<'py, PyDict>> {
        let i = guarded(|| self.inner.frame_info(index))?.map_err(core_error)?;
        let d = PyDict::new(py);
        d.set_item("type", frame_type_name(Some(i.frame_type)))?;
        d.set_item("reference", i.reference)?;
        d.set_item("bytes", i.bytes)?;
        d.set_item("qp", i.qp)?;
        d.set_item("base_bytes", i.base_bytes)?;
        d.set_item("refresh_bytes", i.refresh_bytes)?;
        d.set_item("displacement_bytes", i.displacement_bytes)?;
        Ok(d)
    }

    /// Decodes frame `index`; returns (positions, faces).
    fn decode_frame<'py>(&mut self, py: Python<'py>, index: u32) -> PyResult<MeshArrays<'py>> {
        let inner = &mut self.inner;
        let mesh = released(py, || inner.decode_frame(index))?.map_err(core_error)?;
        Ok(arrays_of(py, mesh))
    }

    /// The payload of frame `index`'s texture unit and its offset in the stream, or None.
    fn texture_payload<'py>(&self, py: Python<'py>, index: u32) -> PyResult<Option<(Bound<'py, PyBytes>, u64)>> {
        let t = guarded(|| self.inner.texture_payload(index))?.map_err(core_error)?;
        Ok(t.map(|(data, offset)| (PyBytes::new(py, data), offset)))
    }

    /// (frame index, (positions, faces)) of the base mesh of the frame decoded last, or None.
    fn last_base<'py>(&self, py: Python<'py>) -> PyResult<Option<(u32, MeshArrays<'py>)>> {
        Ok(guarded(|| self.inner.last_base())?.map(|(i, base)| (i, arrays_of(py, base))))
    }
}

/// A texture unit carrying `payload`, to be placed right after its frame's unit.
#[pyfunction]
fn texture_unit<'py>(py: Python<'py>, payload: &[u8]) -> PyResult<Bound<'py, PyBytes>> {
    Ok(PyBytes::new(py, &guarded(|| bitstream::write_texture_unit(payload))?))
}

/// The texture unit payload of a group (`dynmesh::texturing::TexturePayload`): codec index, atlas
/// width and height, UV bits, frame count, coded atlas, video.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
fn pack_texture_payload<'py>(py: Python<'py>, codec: u8, width: u16, height: u16, uv_bits: u8, frames: u32, atlas: &[u8], video: &[u8]) -> PyResult<Bound<'py, PyBytes>> {
    let p = TexturePayload { codec, width, height, uv_bits, frames, atlas: atlas.to_vec(), video: video.to_vec() };
    Ok(PyBytes::new(py, &guarded(|| p.to_bytes())?))
}

type TextureFields<'py> = (u8, u16, u16, u8, u32, Bound<'py, PyBytes>, Bound<'py, PyBytes>);

/// The fields of a texture unit payload, as `pack_texture_payload` takes them. Raises
/// DecodeError `(message,)` naming what is wrong when it is damaged, UnsupportedError for a
/// payload of another version or an unknown codec.
#[pyfunction]
fn read_texture_payload<'py>(py: Python<'py>, data: &[u8]) -> PyResult<TextureFields<'py>> {
    let p = guarded(|| texturing::read_texture_payload(data))?.map_err(core_error)?;
    Ok((p.codec, p.width, p.height, p.uv_bits, p.frames, PyBytes::new(py, &p.atlas), PyBytes::new(py, &p.video)))
}

/// D1/D2 distortion between a reference and a decoded mesh, sampled on the grid over
/// the box `[box_min, box_max]`. Returns (d1_mse, d2_mse, d1_psnr, d2_psnr).
#[pyfunction]
#[pyo3(signature = (ref_positions, ref_faces, dec_positions, dec_faces, box_min, box_max, peak, grid_size=1024))]
#[allow(clippy::too_many_arguments)]
fn mesh_distortion(
    py: Python<'_>,
    ref_positions: PyReadonlyArray2<'_, f64>,
    ref_faces: PyReadonlyArray2<'_, i64>,
    dec_positions: PyReadonlyArray2<'_, f64>,
    dec_faces: PyReadonlyArray2<'_, i64>,
    box_min: [f64; 3],
    box_max: [f64; 3],
    peak: f64,
    grid_size: u32,
) -> PyResult<(f64, f64, f64, f64)> {
    let a = mesh_of(&ref_positions, &ref_faces)?;
    let b = mesh_of(&dec_positions, &dec_faces)?;
    let grid = colour::grid_of(box_min, box_max, grid_size)?;
    released(py, || sampling::check_sampling((&a.positions, &a.faces), (&b.positions, &b.faces), &grid, false))?.map_err(core_error)?;
    let d = released(py, || {
        let (pa, pb) = rayon::join(|| sampling::sample_grid(&a.positions, &a.faces, &grid), || sampling::sample_grid(&b.positions, &b.faces, &grid));
        metrics::distortion(&pa, &pb)
    })?;
    sampling::check_measured(&[d.d1_mse, d.d2_mse]).map_err(core_error)?;
    Ok((d.d1_mse, d.d2_mse, metrics::psnr(d.d1_mse, peak), metrics::psnr(d.d2_mse, peak)))
}

/// The encoder's default options, keyed as the Python API names them.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    options::register(m)?;
    m.add_class::<Encoder>()?;
    m.add_class::<Decoder>()?;
    m.add_function(wrap_pyfunction!(mesh_distortion, m)?)?;
    m.add_function(wrap_pyfunction!(texture_unit, m)?)?;
    m.add_function(wrap_pyfunction!(pack_texture_payload, m)?)?;
    m.add_function(wrap_pyfunction!(read_texture_payload, m)?)?;
    m.add("TEXTURE_CODECS", TEXTURE_CODECS.to_vec())?;
    m.add("TEXTURE_SIDES", (MIN_SIDE, MAX_SIDE))?;
    colour::register(m)?;
    uv::register(m)?;
    transfer::register(m)?;
    meshio::register(m)?;
    decode_files::register(m)?;
    image::register(m)?;
    errors::register(m)?;
    m.add("MAX_REFERENCES", MAX_REFERENCES)?;
    Ok(())
}
