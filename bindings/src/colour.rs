//! Python bindings of the colour functions: colour PSNR of textured meshes as the common test
//! conditions measure it, snapshot rendering of (decoded) frames, and the conversion between
//! RGB textures and the 10-bit 4:2:0 planes of the texture video.
//!
//! Arrays are checked here (shapes, index ranges, finite values) so that the core's contracts
//! hold and a mistake surfaces as an InputError naming the problem, never as a panic. The core
//! work runs with the GIL released.

use numpy::ndarray::{Array2, Array3};
use numpy::{IntoPyArray, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use dynmesh::eval::metrics;
use dynmesh::eval::render::View;
use dynmesh::eval::sampling::{self, SamplingGrid};
use dynmesh::texturing::{self, Texture, UvMesh};
use dynmesh::Mesh;

use crate::errors::{core_error, input_error, released};
use crate::{faces_of, positions_of};

/// Largest metric grid size (the test conditions use 1024): the ray limit
/// (`MAX_SAMPLE_RAYS`) is what bounds the work, this only catches a typo early.
const MAX_GRID_SIZE: u32 = 16384;

/// Largest image side `render` accepts (keeps a typo from allocating gigabytes).
const MAX_IMAGE_SIDE: usize = 16384;

/// Adds the colour functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(textured_distortion, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(rgb_to_yuv420, m)?)?;
    m.add_function(wrap_pyfunction!(yuv420_to_rgb, m)?)?;
    Ok(())
}

/// Geometry and texture distortion of a decoded textured mesh against the reference, as the
/// common test conditions measure it: both meshes sampled on the grid over `[box_min, box_max]`
/// (normally the reference box) with `grid_size` lines, colours read bilinearly from each mesh's
/// texture at the samples' UVs and rounded to 8 bits, compared in BT.709 YCbCr [0, 1], all as
/// MPEG's mmetric computes them (see the core's `metrics` module).
///
/// Each mesh is positions (N, 3) float64, faces (M, 3) int64, uv (K, 2) float64 (v up, as in
/// OBJ), uv_faces (M, 3) int64 indexing uv per face corner, texture (H, W, 3) uint8 with rows
/// from the top. Returns a dict: d1_psnr, d2_psnr (peak `peak`, the largest side of the
/// sequence's box), y_psnr, cb_psnr, cr_psnr (peak 1; inf when identical) and the matching
/// d1_mse, d2_mse, y_mse, cb_mse, cr_mse.
#[pyfunction]
#[pyo3(signature = (
    ref_positions, ref_faces, ref_uv, ref_uv_faces, ref_texture,
    dec_positions, dec_faces, dec_uv, dec_uv_faces, dec_texture,
    box_min, box_max, peak, grid_size=1024
))]
#[allow(clippy::too_many_arguments)]
fn textured_distortion<'py>(
    py: Python<'py>,
    ref_positions: PyReadonlyArray2<'py, f64>,
    ref_faces: PyReadonlyArray2<'py, i64>,
    ref_uv: PyReadonlyArray2<'py, f64>,
    ref_uv_faces: PyReadonlyArray2<'py, i64>,
    ref_texture: PyReadonlyArray3<'py, u8>,
    dec_positions: PyReadonlyArray2<'py, f64>,
    dec_faces: PyReadonlyArray2<'py, i64>,
    dec_uv: PyReadonlyArray2<'py, f64>,
    dec_uv_faces: PyReadonlyArray2<'py, i64>,
    dec_texture: PyReadonlyArray3<'py, u8>,
    box_min: [f64; 3],
    box_max: [f64; 3],
    peak: f64,
    grid_size: u32,
) -> PyResult<Bound<'py, PyDict>> {
    let named = |what: &'static str| {
        move |e: PyErr| input_error(format!("{what}: {}", e.value(py)))
    };
    let reference = valid_uv_mesh(&ref_positions, &ref_faces, &ref_uv, &ref_uv_faces)
        .map_err(named("reference"))?;
    let decoded = valid_uv_mesh(&dec_positions, &dec_faces, &dec_uv, &dec_uv_faces)
        .map_err(named("decoded"))?;
    let ref_tex = texture_of(&ref_texture).map_err(named("reference texture"))?;
    let dec_tex = texture_of(&dec_texture).map_err(named("decoded texture"))?;
    let grid = grid_of(box_min, box_max, grid_size)?;
    if !(peak.is_finite() && peak > 0.0) {
        return Err(input_error(format!(
            "peak must be a positive finite number, not {peak}"
        )));
    }
    let (r, d) = (&reference.mesh, &decoded.mesh);
    released(py, || sampling::check_sampling((&r.positions, &r.faces), (&d.positions, &d.faces), &grid, true))?.map_err(core_error)?;
    let d = released(py, || metrics::textured_mse(&reference, &ref_tex, &decoded, &dec_tex, &grid))?;
    sampling::check_measured(&[d.geometry.d1_mse, d.geometry.d2_mse]).map_err(core_error)?;
    sampling::check_measured(&d.colour_mse).map_err(core_error)?;
    let [y, cb, cr] = d.colour_mse;
    let [y_psnr, cb_psnr, cr_psnr] = metrics::colour_psnr(d.colour_mse);
    let out = PyDict::new(py);
    out.set_item("d1_psnr", metrics::psnr(d.geometry.d1_mse, peak))?;
    out.set_item("d2_psnr", metrics::psnr(d.geometry.d2_mse, peak))?;
    out.set_item("y_psnr", y_psnr)?;
    out.set_item("cb_psnr", cb_psnr)?;
    out.set_item("cr_psnr", cr_psnr)?;
    out.set_item("d1_mse", d.geometry.d1_mse)?;
    out.set_item("d2_mse", d.geometry.d2_mse)?;
    out.set_item("y_mse", y)?;
    out.set_item("cb_mse", cb)?;
    out.set_item("cr_mse", cr)?;
    Ok(out)
}

/// Renders a mesh into a (height, width, 3) uint8 image: orthographic view from `azimuth`
/// degrees about +y (0 looks along -z at the front, 90 from the +x side) and `elevation`
/// degrees above, the mesh framed to fit with a 5% margin; texture read bilinearly at the
/// interpolated UVs (light grey where there is none), Lambert shading from the camera, white
/// background.
///
/// positions (N, 3) float64 and faces (M, 3) int64; uv (K, 2) float64 and uv_faces (M, 3) int64
/// together, or both None; texture (H, W, 3) uint8 rows from the top, or None. An empty faces
/// array gives a white image.
#[pyfunction]
#[pyo3(signature = (positions, faces, uv, uv_faces, texture, width, height, azimuth=0.0, elevation=0.0))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    uv: Option<PyReadonlyArray2<'py, f64>>,
    uv_faces: Option<PyReadonlyArray2<'py, i64>>,
    texture: Option<PyReadonlyArray3<'py, u8>>,
    width: usize,
    height: usize,
    azimuth: f64,
    elevation: f64,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    for (name, side) in [("width", width), ("height", height)] {
        if !(1..=MAX_IMAGE_SIDE).contains(&side) {
            return Err(input_error(format!(
                "{name} must be from 1 to {MAX_IMAGE_SIDE}, not {side}"
            )));
        }
    }
    if !(azimuth.is_finite() && elevation.is_finite()) {
        return Err(input_error("azimuth and elevation must be finite"));
    }
    let mesh = match (&uv, &uv_faces) {
        (Some(uv), Some(uv_faces)) => uv_mesh_of(&positions, &faces, uv, uv_faces)?,
        (None, None) => {
            let p = positions_of(&positions)?;
            let f = faces_of(&faces, p.len())?;
            UvMesh { mesh: Mesh::new(p, f), ..UvMesh::default() }
        }
        _ => return Err(input_error("give both uv and uv_faces, or neither")),
    };
    if !mesh.mesh.faces.is_empty() {
        let check = if mesh.uv_faces.is_empty() {
            mesh.mesh.validate().map_err(|e| e.0)
        } else {
            mesh.validate()
        };
        check.map_err(input_error)?;
    }
    let texture = texture.as_ref().map(texture_of).transpose()?;
    let view = View { azimuth_deg: azimuth, elevation_deg: elevation };
    let image = released(py, || dynmesh::eval::render::render(&mesh, texture.as_ref(), width, height, view))?;
    let flat = image.rgb.into_flattened();
    Ok(Array3::from_shape_vec((height, width, 3), flat).expect("shape").into_pyarray(py))
}

/// An (H, W, 3) uint8 RGB image (H and W even) as FFmpeg's yuv420p10le frame: a (3H/2, W)
/// uint16 array holding full-range 10-bit BT.709 Y, then Cb and Cr averaged over 2 x 2 texels.
#[pyfunction]
fn rgb_to_yuv420<'py>(py: Python<'py>, image: PyReadonlyArray3<'py, u8>) -> PyResult<Bound<'py, PyArray2<u16>>> {
    let t = texture_of(&image)?;
    if t.width % 2 != 0 || t.height % 2 != 0 {
        return Err(input_error(format!("4:2:0 needs even sides, not {}x{}", t.width, t.height)));
    }
    let (w, h) = (t.width, t.height);
    let planes = released(py, || texturing::yuv420_10bit(&t))?;
    Ok(Array2::from_shape_vec((h * 3 / 2, w), planes).expect("shape").into_pyarray(py))
}

/// The inverse of `rgb_to_yuv420`: a (3H/2, W) uint16 yuv420p10le frame to (H, W, 3) uint8
/// RGB, each chroma sample used for its 2 x 2 texels.
#[pyfunction]
fn yuv420_to_rgb<'py>(py: Python<'py>, planes: PyReadonlyArray2<'py, u16>) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let v = planes.as_array();
    let (rows, width) = v.dim();
    if rows % 3 != 0 {
        return Err(input_error(format!("a 4:2:0 frame has 3H/2 rows, not {rows}")));
    }
    let height = rows * 2 / 3;
    let v = v.as_standard_layout();
    let samples = v.as_slice().expect("standard layout is contiguous");
    let t = released(py, || texturing::rgb_of_yuv420_10bit(samples, width, height))?.map_err(core_error)?;
    let flat = t.rgb.into_flattened();
    Ok(Array3::from_shape_vec((height, width, 3), flat).expect("shape").into_pyarray(py))
}

/// A textured mesh from arrays, checked as [`UvMesh::validate`] checks it.
pub(crate) fn valid_uv_mesh(
    positions: &PyReadonlyArray2<f64>,
    faces: &PyReadonlyArray2<i64>,
    uv: &PyReadonlyArray2<f64>,
    uv_faces: &PyReadonlyArray2<i64>,
) -> PyResult<UvMesh> {
    let mesh = uv_mesh_of(positions, faces, uv, uv_faces)?;
    mesh.validate().map_err(input_error)?;
    Ok(mesh)
}

/// A textured mesh from arrays whose shapes and index ranges are checked (not its values).
fn uv_mesh_of(
    positions: &PyReadonlyArray2<f64>,
    faces: &PyReadonlyArray2<i64>,
    uv: &PyReadonlyArray2<f64>,
    uv_faces: &PyReadonlyArray2<i64>,
) -> PyResult<UvMesh> {
    let p = positions_of(positions)?;
    let f = faces_of(faces, p.len())?;
    let uv = uv_of(uv)?;
    let uv_faces = uv_faces_of(uv_faces, f.len(), uv.len())?;
    Ok(UvMesh { mesh: Mesh::new(p, f), uv, uv_faces })
}

pub(crate) fn uv_of(a: &PyReadonlyArray2<f64>) -> PyResult<Vec<[f64; 2]>> {
    let v = a.as_array();
    if v.ncols() != 2 {
        return Err(input_error("uv must have shape (K, 2)"));
    }
    Ok(v.rows().into_iter().map(|r| [r[0], r[1]]).collect())
}

/// UV index triangles: one row of 3 indices per face, into a list of `uv_count` UVs.
pub(crate) fn uv_faces_of(
    a: &PyReadonlyArray2<i64>,
    face_count: usize,
    uv_count: usize,
) -> PyResult<Vec<[u32; 3]>> {
    let v = a.as_array();
    if v.ncols() != 3 || v.nrows() != face_count {
        return Err(input_error(format!(
            "uv_faces must have shape ({face_count}, 3), one row per face"
        )));
    }
    v.rows()
        .into_iter()
        .enumerate()
        .map(|(i, r)| {
            let t = [r[0], r[1], r[2]];
            if t.iter().any(|&x| x < 0 || x as u64 >= uv_count as u64) {
                return Err(input_error(format!(
                    "uv_faces row {i} refers to a UV that does not exist (there are {uv_count}, numbered from 0)"
                )));
            }
            Ok(t.map(|x| x as u32))
        })
        .collect()
}

/// An RGB texture from an (H, W, 3) uint8 array, rows from the top.
pub(crate) fn texture_of(a: &PyReadonlyArray3<u8>) -> PyResult<Texture> {
    let v = a.as_array();
    let (height, width, channels) = v.dim();
    if channels != 3 || width == 0 || height == 0 {
        return Err(input_error(format!(
            "texture must have shape (H, W, 3) with H, W >= 1, not ({height}, {width}, {channels})"
        )));
    }
    let v = v.as_standard_layout();
    let bytes = v.as_slice().expect("standard layout is contiguous");
    Ok(Texture { width, height, rgb: bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect() })
}

/// mmetric's sampling grid over a finite, non-inverted box.
pub(crate) fn grid_of(box_min: [f64; 3], box_max: [f64; 3], grid_size: u32) -> PyResult<SamplingGrid> {
    if !(2..=MAX_GRID_SIZE).contains(&grid_size) {
        return Err(input_error(format!("grid size must be from 2 to {MAX_GRID_SIZE}, not {grid_size}")));
    }
    let finite = box_min.iter().chain(&box_max).all(|v| v.is_finite());
    if !finite || (0..3).any(|k| box_min[k] > box_max[k]) {
        return Err(input_error(format!(
            "box must be finite with box_min <= box_max, not from {box_min:?} to {box_max:?}"
        )));
    }
    Ok(SamplingGrid::over_box(box_min, box_max, grid_size))
}
