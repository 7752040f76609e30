//! Thin bindings to the xatlas C++ library (Jonathan Young, <https://github.com/jpcy/xatlas>)
//! as vendored and compiled by the `xatlas-rs` 0.1.3 crate.
//!
//! That crate's own Rust bindings carry MSVC symbol names and do not link on Linux, so this
//! module declares the few entry points it needs with their Itanium C++ ABI link names
//! (`nm libxatlas.a` lists them) and `#[repr(C)]` mirrors of the structs in `xatlas.h`.
//! Everything `unsafe` in the crate lives here; the safe [`generate`] copies the results out
//! and destroys the atlas before returning.
//!
//! The structs passed by value (`ChartOptions`, `PackOptions`) have trivial copy constructors
//! and destructors, so the Itanium ABI passes them exactly like C structs, which is what
//! `extern "C"` does on the Rust side.
#![allow(unsafe_code)]

use std::cell::Cell;
use std::ffi::c_void;
use std::sync::Once;

// Keep the static library built by xatlas-rs on the link line.
use xatlas_rs as _;

mod ffi {
    use std::ffi::{c_char, c_int, c_void};

    #[repr(C)]
    pub struct Chart {
        pub atlas_index: u32,
        pub index_array: *mut u32,
        pub index_count: u32,
    }

    #[repr(C)]
    pub struct Vertex {
        pub atlas_index: i32,
        pub uv: [f32; 2],
        pub xref: u32,
    }

    #[repr(C)]
    pub struct Mesh {
        pub chart_array: *mut Chart,
        pub chart_count: u32,
        pub index_array: *mut u32,
        pub index_count: u32,
        pub vertex_array: *mut Vertex,
        pub vertex_count: u32,
    }

    #[repr(C)]
    pub struct Atlas {
        pub width: u32,
        pub height: u32,
        pub atlas_count: u32,
        pub chart_count: u32,
        pub mesh_count: u32,
        pub meshes: *mut Mesh,
        pub utilization: *mut f32,
        pub texels_per_unit: f32,
    }

    /// `xatlas::IndexFormat::UInt32`.
    pub const INDEX_FORMAT_U32: u32 = 1;

    #[repr(C)]
    pub struct MeshDecl {
        pub vertex_count: u32,
        pub vertex_position_data: *const c_void,
        pub vertex_position_stride: u32,
        pub vertex_normal_data: *const c_void,
        pub vertex_normal_stride: u32,
        pub vertex_uv_data: *const c_void,
        pub vertex_uv_stride: u32,
        pub index_count: u32,
        pub index_data: *const c_void,
        pub index_offset: i32,
        pub index_format: u32,
        pub face_ignore_data: *const bool,
    }

    #[repr(C)]
    #[derive(Clone, Copy)]
    pub struct ChartOptions {
        pub max_chart_area: f32,
        pub max_boundary_length: f32,
        pub proxy_fit_metric_weight: f32,
        pub roundness_metric_weight: f32,
        pub straightness_metric_weight: f32,
        pub normal_seam_metric_weight: f32,
        pub texture_seam_metric_weight: f32,
        pub max_threshold: f32,
        pub grow_face_count: u32,
        pub max_iterations: u32,
    }

    #[repr(C)]
    #[derive(Clone, Copy)]
    pub struct PackOptions {
        pub attempts: c_int,
        pub texels_per_unit: f32,
        pub resolution: u32,
        pub max_chart_size: u32,
        pub block_align: bool,
        pub conservative: bool,
        pub padding: u32,
    }

    pub type ProgressFunc = Option<unsafe extern "C" fn(u32, c_int, *mut c_void)>;
    pub type ParameterizeFunc =
        Option<unsafe extern "C" fn(*const f32, *mut f32, u32, *const u32, u32, bool)>;
    pub type PrintFunc = Option<unsafe extern "C" fn(*const c_char, ...) -> c_int>;

    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    unsafe extern "C" {
        /// glibc: returns the free memory of every malloc arena to the system.
        pub fn malloc_trim(pad: usize) -> c_int;
    }

    unsafe extern "C" {
        #[link_name = "_ZN6xatlas6CreateEv"]
        pub fn create() -> *mut Atlas;
        #[link_name = "_ZN6xatlas7DestroyEPNS_5AtlasE"]
        pub fn destroy(atlas: *mut Atlas);
        #[link_name = "_ZN6xatlas7AddMeshEPNS_5AtlasERKNS_8MeshDeclE"]
        pub fn add_mesh(atlas: *mut Atlas, decl: *const MeshDecl) -> u32;
        #[link_name = "_ZN6xatlas13ComputeChartsEPNS_5AtlasENS_12ChartOptionsEPFvNS_16ProgressCategory4EnumEiPvES5_"]
        pub fn compute_charts(
            atlas: *mut Atlas,
            options: ChartOptions,
            progress: ProgressFunc,
            user: *mut c_void,
        );
        #[link_name = "_ZN6xatlas18ParameterizeChartsEPNS_5AtlasEPFvPKfPfjPKjjbEPFvNS_16ProgressCategory4EnumEiPvESB_"]
        pub fn parameterize_charts(
            atlas: *mut Atlas,
            func: ParameterizeFunc,
            progress: ProgressFunc,
            user: *mut c_void,
        );
        #[link_name = "_ZN6xatlas10PackChartsEPNS_5AtlasENS_11PackOptionsEPFvNS_16ProgressCategory4EnumEiPvES5_"]
        pub fn pack_charts(
            atlas: *mut Atlas,
            options: PackOptions,
            progress: ProgressFunc,
            user: *mut c_void,
        );
        #[link_name = "_ZN6xatlas8SetPrintEPFiPKczEb"]
        pub fn set_print(print: PrintFunc, verbose: bool);
    }
}

/// Chart segmentation options (`xatlas::ChartOptions`; defaults as in `xatlas.h`).
#[derive(Clone, Copy, Debug)]
pub struct ChartOptions {
    /// Do not grow charts beyond this area (mesh units²); 0 = no limit.
    pub max_chart_area: f32,
    /// Do not grow charts beyond this boundary length (mesh units); 0 = no limit.
    pub max_boundary_length: f32,
    /// Cost weight of the angle between a face and the chart's mean normal. Default 2.
    pub proxy_fit_metric_weight: f32,
    /// Cost weight of chart roundness. Default 0.01.
    pub roundness_metric_weight: f32,
    /// Cost weight of chart boundary straightness. Default 6.
    pub straightness_metric_weight: f32,
    /// Cost weight of crossing a normal seam; above 1000 seams are always respected. Default 4.
    pub normal_seam_metric_weight: f32,
    /// Cost weight of crossing a UV0 seam. Default 0.5.
    pub texture_seam_metric_weight: f32,
    /// Stop growing a chart when the weighted cost exceeds this. Default 2.
    pub max_threshold: f32,
    /// Faces added per growth step. Default 32.
    pub grow_face_count: u32,
    /// Seeding/growing iterations. Default 1.
    pub max_iterations: u32,
}

impl Default for ChartOptions {
    fn default() -> Self {
        Self {
            max_chart_area: 0.0,
            max_boundary_length: 0.0,
            proxy_fit_metric_weight: 2.0,
            roundness_metric_weight: 0.01,
            straightness_metric_weight: 6.0,
            normal_seam_metric_weight: 4.0,
            texture_seam_metric_weight: 0.5,
            max_threshold: 2.0,
            grow_face_count: 32,
            max_iterations: 1,
        }
    }
}

/// Chart packing options (`xatlas::PackOptions`).
#[derive(Clone, Copy, Debug)]
pub struct PackOptions {
    /// Random placement attempts per chart; 0 = brute force (slow, tightest). Default 4096.
    pub attempts: i32,
    /// Texels per mesh unit; 0 = derive from `resolution`.
    pub texels_per_unit: f32,
    /// 0 = one atlas sized to fit; otherwise one or more atlases of exactly this size.
    pub resolution: u32,
    /// Charts larger than this (texels) are scaled down. Default 1024.
    pub max_chart_size: u32,
    /// Align charts to 4×4 blocks.
    pub block_align: bool,
    /// Empty texels between charts (xatlas' conservative packing).
    pub padding: u32,
}

impl Default for PackOptions {
    fn default() -> Self {
        Self {
            attempts: 4096,
            texels_per_unit: 0.0,
            resolution: 0,
            max_chart_size: 1024,
            block_align: false,
            padding: 0,
        }
    }
}

/// One triangle mesh handed to xatlas.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// Vertex positions (mesh units).
    pub positions: &'a [[f32; 3]],
    /// Optional vertex normals (used as chart-segmentation hints).
    pub normals: Option<&'a [[f32; 3]]>,
    /// Optional UV0 (used as seam hints).
    pub uvs: Option<&'a [[f32; 2]]>,
    /// Triangle list indices into the vertex arrays.
    pub indices: &'a [u32],
}

/// One output vertex: a copy of input vertex `xref` placed at `uv` (texels) in atlas `atlas_index`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputVertex {
    /// Sub-atlas index, or -1 when the vertex belongs only to ignored (degenerate) faces.
    pub atlas_index: i32,
    /// Position in the atlas, in texels (0..width, 0..height).
    pub uv: [f32; 2],
    /// Index of the input vertex this one was copied from.
    pub xref: u32,
}

/// Result of unwrapping one mesh.
#[derive(Clone, Debug, Default)]
pub struct Output {
    /// Atlas width in texels.
    pub width: u32,
    /// Atlas height in texels.
    pub height: u32,
    /// Output vertices (input vertices split along chart seams).
    pub vertices: Vec<OutputVertex>,
    /// Output triangle list; triangle `t` corresponds to input triangle `t`.
    pub indices: Vec<u32>,
    /// Chart of each output triangle, or `u32::MAX` for faces xatlas ignored (degenerate).
    pub triangle_charts: Vec<u32>,
    /// Number of charts.
    pub chart_count: u32,
}

/// Why xatlas refused a mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum XatlasError {
    /// An index is not below the vertex count.
    #[error("index out of range")]
    IndexOutOfRange,
    /// The index count is not a multiple of three.
    #[error("index count is not a multiple of 3")]
    InvalidIndexCount,
    /// A normal or UV array does not have one entry per position.
    #[error("normal or UV array length differs from the position count")]
    AttributeLength,
    /// More than `u32::MAX` vertices or indices.
    #[error("mesh too large for xatlas (more than 2^32 vertices or indices)")]
    TooLarge,
    /// xatlas returned an unexpected error code.
    #[error("xatlas error code {0}")]
    Other(u32),
}

thread_local! {
    /// Cores xatlas' workers may run on when started from this thread (0: every core).
    static THREAD_LIMIT: Cell<usize> = const { Cell::new(0) };
}

/// Runs `f` with xatlas' workers (started by [`generate`] on this thread) kept to `threads`
/// cores (0: no limit).
pub fn with_thread_limit<T>(threads: usize, f: impl FnOnce() -> T) -> T {
    let old = THREAD_LIMIT.with(|c| c.replace(threads));
    let out = f();
    THREAD_LIMIT.with(|c| c.set(old));
    out
}

/// Restores the calling thread's CPU affinity when dropped.
struct Affinity(#[cfg(target_os = "linux")] Option<libc::cpu_set_t>);

/// Keeps the calling thread (and the threads it starts) to the first `threads` of the cores
/// it may run on, until the returned guard drops; nothing when `threads` is 0 or not fewer.
#[cfg(target_os = "linux")]
fn limit_affinity(threads: usize) -> Affinity {
    if threads == 0 {
        return Affinity(None);
    }
    // SAFETY: a zeroed `cpu_set_t` is a valid empty set; `sched_getaffinity` writes at most
    // `size_of::<cpu_set_t>()` bytes into it for the calling thread (pid 0).
    let mut old: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    let size = size_of::<libc::cpu_set_t>();
    // SAFETY: as above.
    if unsafe { libc::sched_getaffinity(0, size, &mut old) } != 0 {
        return Affinity(None);
    }
    // SAFETY: zeroed sets are valid; the CPU_* helpers read and write within the set.
    let mut new: libc::cpu_set_t = unsafe { std::mem::zeroed() };
    let mut kept = 0;
    for cpu in 0..libc::CPU_SETSIZE as usize {
        // SAFETY: `cpu` is below `CPU_SETSIZE`.
        if kept < threads && unsafe { libc::CPU_ISSET(cpu, &old) } {
            // SAFETY: as above.
            unsafe { libc::CPU_SET(cpu, &mut new) };
            kept += 1;
        }
    }
    // SAFETY: `old` is the set read above.
    let total = unsafe { libc::CPU_COUNT(&old) } as usize;
    if kept == 0 || kept >= total {
        return Affinity(None);
    }
    // SAFETY: `new` is a valid, non-empty subset of the thread's allowed cores.
    if unsafe { libc::sched_setaffinity(0, size, &new) } != 0 {
        return Affinity(None);
    }
    Affinity(Some(old))
}

#[cfg(not(target_os = "linux"))]
fn limit_affinity(_threads: usize) -> Affinity {
    Affinity()
}

impl Drop for Affinity {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        if let Some(old) = self.0 {
            // SAFETY: `old` is the set this thread had before `limit_affinity`.
            unsafe { libc::sched_setaffinity(0, size_of::<libc::cpu_set_t>(), &old) };
        }
    }
}

fn silence_xatlas_output() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // SAFETY: `SetPrint` only stores the pointer (null disables printing) in a global that
        // is read by the printing macros; called once before any other xatlas use.
        unsafe { ffi::set_print(None, false) };
    });
}

/// Owns an `xatlas::Atlas*` and destroys it on drop (also on early return).
struct AtlasHandle(*mut ffi::Atlas);

/// An atlas on its way to `xatlas::Destroy` on another thread.
struct Doomed(*mut ffi::Atlas);

// SAFETY: after `drop` hands it over, nothing else refers to the atlas; xatlas' `Destroy` may
// run on any thread (it only stops the atlas' own worker threads and frees its memory).
unsafe impl Send for Doomed {}

impl Drop for AtlasHandle {
    /// Destroys the atlas on a detached thread. The bundled xatlas' task scheduler has a lost
    /// wake-up in its shutdown: a worker that checks the running flag just before `Destroy`
    /// clears it, and only then parks, is never woken, and `Destroy` waits forever joining it.
    /// We saw this hang a bake (the study's 80 bakes, and a plugin test under load), with every
    /// result already copied out. Off the bake's thread, such a hang costs one parked thread
    /// and the atlas' memory instead of the bake.
    fn drop(&mut self) {
        let doomed = Doomed(self.0);
        let destroy = move || {
            let doomed = doomed;
            // SAFETY: the pointer came from `xatlas::Create` and is destroyed exactly once here;
            // the handle that owned it is being dropped.
            unsafe { ffi::destroy(doomed.0) };
            // xatlas allocates on its worker threads, so glibc gives them arenas of their
            // own, which keep what xatlas freed resident for the rest of the bake (60 MiB of
            // the house's 1.2 M-texel bake, above what the memory plan counts).
            #[cfg(all(target_os = "linux", target_env = "gnu"))]
            // SAFETY: malloc_trim only returns free pages; no pointer is involved.
            unsafe {
                ffi::malloc_trim(0);
            }
        };
        // No thread to spare (spawn fails): the atlas leaks rather than risk the hang.
        let _ = std::thread::Builder::new()
            .name("xatlas-destroy".into())
            .spawn(destroy);
    }
}

/// Unwraps one triangle mesh: segments it into charts, parameterizes and packs them.
///
/// The chart pass runs on xatlas' own worker threads; the result depends only on the input
/// (xatlas seeds its random packer with a constant).
///
/// # Errors
/// [`XatlasError`] when the index data is invalid.
pub fn generate(
    input: &Input<'_>,
    chart_options: &ChartOptions,
    pack_options: &PackOptions,
) -> Result<Output, XatlasError> {
    silence_xatlas_output();
    let vertex_count = u32::try_from(input.positions.len()).map_err(|_| XatlasError::TooLarge)?;
    let index_count = u32::try_from(input.indices.len()).map_err(|_| XatlasError::TooLarge)?;
    if index_count % 3 != 0 {
        return Err(XatlasError::InvalidIndexCount);
    }
    if input.indices.iter().any(|&i| i >= vertex_count) {
        return Err(XatlasError::IndexOutOfRange);
    }
    if input
        .normals
        .is_some_and(|n| n.len() != input.positions.len())
        || input.uvs.is_some_and(|u| u.len() != input.positions.len())
    {
        return Err(XatlasError::AttributeLength);
    }
    if index_count == 0 {
        return Ok(Output::default());
    }

    let decl = ffi::MeshDecl {
        vertex_count,
        vertex_position_data: input.positions.as_ptr().cast::<c_void>(),
        vertex_position_stride: 12,
        vertex_normal_data: input
            .normals
            .map_or(std::ptr::null(), |n| n.as_ptr().cast::<c_void>()),
        vertex_normal_stride: if input.normals.is_some() { 12 } else { 0 },
        vertex_uv_data: input
            .uvs
            .map_or(std::ptr::null(), |u| u.as_ptr().cast::<c_void>()),
        vertex_uv_stride: if input.uvs.is_some() { 8 } else { 0 },
        index_count,
        index_data: input.indices.as_ptr().cast::<c_void>(),
        index_offset: 0,
        index_format: ffi::INDEX_FORMAT_U32,
        face_ignore_data: std::ptr::null(),
    };
    let chart = ffi::ChartOptions {
        max_chart_area: chart_options.max_chart_area,
        max_boundary_length: chart_options.max_boundary_length,
        proxy_fit_metric_weight: chart_options.proxy_fit_metric_weight,
        roundness_metric_weight: chart_options.roundness_metric_weight,
        straightness_metric_weight: chart_options.straightness_metric_weight,
        normal_seam_metric_weight: chart_options.normal_seam_metric_weight,
        texture_seam_metric_weight: chart_options.texture_seam_metric_weight,
        max_threshold: chart_options.max_threshold,
        grow_face_count: chart_options.grow_face_count,
        max_iterations: chart_options.max_iterations,
    };
    let pack = ffi::PackOptions {
        attempts: pack_options.attempts,
        texels_per_unit: pack_options.texels_per_unit,
        resolution: pack_options.resolution,
        max_chart_size: pack_options.max_chart_size,
        block_align: pack_options.block_align,
        conservative: pack_options.padding > 0,
        padding: pack_options.padding,
    };

    // xatlas starts a worker per core in `Create`; they inherit the creating thread's CPU
    // affinity, so a bake limited to N threads keeps xatlas to N cores.
    let restore = limit_affinity(THREAD_LIMIT.with(Cell::get));
    // SAFETY: `Create` has no preconditions and returns a fresh atlas owned by `handle`.
    let handle = AtlasHandle(unsafe { ffi::create() });
    drop(restore);
    assert!(!handle.0.is_null(), "xatlas::Create returned null");
    // SAFETY: `decl` points at slices that outlive the call (xatlas copies the data); the
    // strides match the element types and every index was checked against `vertex_count`.
    let code = unsafe { ffi::add_mesh(handle.0, &decl) };
    match code {
        0 => {}
        1 => return Err(XatlasError::IndexOutOfRange),
        2 => return Err(XatlasError::InvalidIndexCount),
        other => return Err(XatlasError::Other(other)),
    }
    // SAFETY: the atlas holds one mesh; the three calls are made in the order xatlas requires,
    // with no callbacks (null function pointers are allowed by the API).
    unsafe {
        ffi::compute_charts(handle.0, chart, None, std::ptr::null_mut());
        ffi::parameterize_charts(handle.0, None, None, std::ptr::null_mut());
        ffi::pack_charts(handle.0, pack, None, std::ptr::null_mut());
    }
    // SAFETY: after `PackCharts` the atlas and its `meshes` array (length `mesh_count`) are
    // valid until `Destroy`, which only runs when `handle` drops at the end of this function.
    let atlas = unsafe { &*handle.0 };
    let mut out = Output {
        width: atlas.width,
        height: atlas.height,
        chart_count: 0,
        ..Output::default()
    };
    if atlas.mesh_count != 1 || atlas.meshes.is_null() {
        return Ok(out);
    }
    // SAFETY: `meshes` has `mesh_count == 1` elements (checked above).
    let mesh = unsafe { &*atlas.meshes };
    // SAFETY: each array pointer is valid for its count, as filled in by `PackCharts`.
    let (vertices, indices, charts) = unsafe {
        (
            raw_slice(mesh.vertex_array, mesh.vertex_count),
            raw_slice(mesh.index_array, mesh.index_count),
            raw_slice(mesh.chart_array, mesh.chart_count),
        )
    };
    out.vertices = vertices
        .iter()
        .map(|v| OutputVertex {
            atlas_index: v.atlas_index,
            uv: v.uv,
            xref: v.xref,
        })
        .collect();
    out.indices = indices.to_vec();
    out.chart_count = mesh.chart_count;

    // Chart of each output vertex, then of each triangle (vertices are never shared
    // between charts in xatlas' output).
    let mut vertex_chart = vec![u32::MAX; out.vertices.len()];
    for (chart_index, chart) in charts.iter().enumerate() {
        // SAFETY: `index_array` holds `index_count` vertex indices of this chart.
        let chart_indices = unsafe { raw_slice(chart.index_array, chart.index_count) };
        for &v in chart_indices {
            if let Some(slot) = vertex_chart.get_mut(v as usize) {
                *slot = chart_index as u32;
            }
        }
    }
    out.triangle_charts = out
        .indices
        .chunks_exact(3)
        .map(|t| vertex_chart.get(t[0] as usize).copied().unwrap_or(u32::MAX))
        .collect();
    Ok(out)
}

/// # Safety
/// `ptr` must be valid for `len` reads of `T` (or `len` must be 0) for the returned lifetime.
unsafe fn raw_slice<'a, T>(ptr: *const T, len: u32) -> &'a [T] {
    if len == 0 || ptr.is_null() {
        &[]
    } else {
        // SAFETY: guaranteed by the caller.
        unsafe { std::slice::from_raw_parts(ptr, len as usize) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube() -> (Vec<[f32; 3]>, Vec<u32>) {
        let mut p = Vec::new();
        let mut idx = Vec::new();
        // Six faces, four vertices each.
        let faces: [([f32; 3], [f32; 3], [f32; 3]); 6] = [
            ([1., 0., 0.], [0., 1., 0.], [0., 0., 1.]),
            ([-1., 0., 0.], [0., 0., 1.], [0., 1., 0.]),
            ([0., 1., 0.], [0., 0., 1.], [1., 0., 0.]),
            ([0., -1., 0.], [1., 0., 0.], [0., 0., 1.]),
            ([0., 0., 1.], [1., 0., 0.], [0., 1., 0.]),
            ([0., 0., -1.], [0., 1., 0.], [1., 0., 0.]),
        ];
        for (n, u, v) in faces {
            let base = p.len() as u32;
            for (a, b) in [(-1., -1.), (1., -1.), (1., 1.), (-1., 1.)] {
                p.push([
                    n[0] + a * u[0] + b * v[0],
                    n[1] + a * u[1] + b * v[1],
                    n[2] + a * u[2] + b * v[2],
                ]);
            }
            idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        (p, idx)
    }

    #[test]
    fn cube_unwraps_into_charts_inside_the_atlas() {
        let (positions, indices) = cube();
        let out = generate(
            &Input {
                positions: &positions,
                normals: None,
                uvs: None,
                indices: &indices,
            },
            &ChartOptions::default(),
            &PackOptions {
                texels_per_unit: 8.0,
                padding: 2,
                ..PackOptions::default()
            },
        )
        .unwrap();
        assert!(out.width > 0 && out.height > 0);
        assert_eq!(out.indices.len(), indices.len());
        assert!(out.chart_count >= 1);
        for v in &out.vertices {
            assert!(v.uv[0] >= 0.0 && v.uv[0] <= out.width as f32);
            assert!(v.uv[1] >= 0.0 && v.uv[1] <= out.height as f32);
            assert!((v.xref as usize) < positions.len());
        }
        assert!(out.triangle_charts.iter().all(|&c| c < out.chart_count));
    }

    #[test]
    fn bad_indices_are_refused() {
        let (positions, mut indices) = cube();
        indices[4] = 99;
        let err = generate(
            &Input {
                positions: &positions,
                normals: None,
                uvs: None,
                indices: &indices,
            },
            &ChartOptions::default(),
            &PackOptions::default(),
        )
        .unwrap_err();
        assert_eq!(err, XatlasError::IndexOutOfRange);
    }
}
