//! The compiler alone, for engines that record their own passes: declare resources and
//! passes, compile with a profile, and walk the plan — render passes with their attachments'
//! load/store ops, subpasses, barriers — to record it with their own code.

use std::ffi::c_char;

use tilegraph_graph::{
    BufferId, ClearColor, ClearDepthStencil, Extent2d, Format, GraphBuilder, ImageDesc, ImageId,
    Import, InitialContent, PassClass, PassId, ResourceId,
};
use tilegraph_profile::ProfileSet;

use crate::plan::{PlanObject, TgPlan};
use crate::registry::{self, Kind};
use crate::renderer::TgImageState;
use crate::status::{arg, array, boundary, optional_string, out, string, Failure, TgStatus};

/// A frame graph being declared.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TgGraph {
    pub raw: u64,
}

/// How a pass uses a resource besides attachments (`tg_pass_use`).
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgUse {
    Sampled = 0,
    StorageRead = 1,
    StorageWrite = 2,
    StorageReadWrite = 3,
    Uniform = 4,
    Indirect = 5,
    /// An input attachment (raster passes; merged passes read it from tile memory).
    Input = 6,
}

/// The pass classes of a profile's pass order.
fn pass_class_of(raw: u32) -> Result<PassClass, Failure> {
    Ok(match raw {
        0 => PassClass::Compute,
        1 => PassClass::DepthPrepass,
        2 => PassClass::Opaque,
        3 => PassClass::AlphaTested,
        4 => PassClass::Transparent,
        5 => PassClass::OcclusionQuery,
        6 => PassClass::Post,
        7 => PassClass::Transfer,
        8 => PassClass::Other,
        9 => PassClass::Shadow,
        _ => {
            return Err(Failure::invalid(format!(
                "pass class {raw} is no TgPassClass"
            )))
        }
    })
}

/// The class of a pass, which orders it in the profile's pass order.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TgPassClass {
    Compute = 0,
    DepthPrepass = 1,
    Opaque = 2,
    AlphaTested = 3,
    Transparent = 4,
    OcclusionQuery = 5,
    Post = 6,
    Transfer = 7,
    Other = 8,
    /// Shadow maps: depth from a light, sampled by the colour passes after it.
    Shadow = 9,
}

pub(crate) struct GraphObject {
    graph: GraphBuilder<()>,
}

/// An empty graph.
///
/// # Safety
/// `out_graph` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_create(out_graph: *mut TgGraph) -> TgStatus {
    boundary("tg_graph_create", || {
        // SAFETY: the caller's contract.
        let out_graph = unsafe { out(out_graph, "out_graph") }?;
        let object = GraphObject {
            graph: GraphBuilder::new(),
        };
        *out_graph = TgGraph {
            raw: registry::insert(Kind::Graph, object)?,
        };
        Ok(())
    })
}

/// Destroys a graph. A zero handle is a no-op.
#[no_mangle]
pub extern "C" fn tg_graph_destroy(graph: TgGraph) -> TgStatus {
    boundary("tg_graph_destroy", || {
        if graph.raw == 0 {
            return Ok(());
        }
        registry::remove::<GraphObject>(graph.raw, Kind::Graph, "graph").map(drop)
    })
}

fn on_graph<R>(
    graph: TgGraph,
    f: impl FnOnce(&mut GraphBuilder<()>) -> Result<R, Failure>,
) -> Result<R, Failure> {
    let mut g = registry::take::<GraphObject>(graph.raw, Kind::Graph, "graph")?;
    let result = f(&mut g.graph);
    registry::put_back(graph.raw, Kind::Graph, g);
    result
}

fn image_desc(width: u32, height: u32, format: i32) -> Result<ImageDesc, Failure> {
    if width == 0 || height == 0 {
        return Err(Failure::invalid(format!(
            "image size {width}x{height} is empty"
        )));
    }
    let format = Format::from_vk_raw(format).ok_or_else(|| {
        Failure::invalid(format!("VkFormat {format} is not a format of the graph's"))
    })?;
    Ok(ImageDesc::new(Extent2d::new(width, height), format))
}

fn resource_id(g: &GraphBuilder<()>, id: u32, name: &str) -> Result<ImageId, Failure> {
    if (id as usize) < g.resource_count() {
        Ok(ImageId(ResourceId(id)))
    } else {
        Err(Failure::invalid(format!(
            "`{name}` {id} is no resource of the graph"
        )))
    }
}

/// Declares an image the graph creates (and may keep in tile memory, alias or prune).
///
/// # Safety
/// `name` is a NUL-terminated string; `out_id` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_create_image(
    graph: TgGraph,
    name: *const c_char,
    width: u32,
    height: u32,
    format: i32,
    out_id: *mut u32,
) -> TgStatus {
    boundary("tg_graph_create_image", || {
        // SAFETY: the caller's contract.
        let (name, out_id) = unsafe { (string(name, "name")?, out(out_id, "out_id")?) };
        let desc = image_desc(width, height, format)?;
        *out_id = on_graph(graph, |g| Ok(g.create_image(name, desc).0 .0))?;
        Ok(())
    })
}

/// Declares the caller's image: its state now, whether its content matters
/// (`keep_content` non-zero: loaded), and the state the frame must leave it in.
///
/// # Safety
/// `name` is a NUL-terminated string; `initial` and `final_state` are valid; `out_id` is
/// writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_import_image(
    graph: TgGraph,
    name: *const c_char,
    width: u32,
    height: u32,
    format: i32,
    initial: *const TgImageState,
    keep_content: u32,
    final_state: *const TgImageState,
    out_id: *mut u32,
) -> TgStatus {
    boundary("tg_graph_import_image", || {
        // SAFETY: the caller's contract.
        let (name, initial, final_state, out_id) = unsafe {
            (
                string(name, "name")?,
                arg(initial, "initial")?,
                arg(final_state, "final_state")?,
                out(out_id, "out_id")?,
            )
        };
        let desc = image_desc(width, height, format)?;
        let import = Import {
            initial: crate::renderer::state(initial, "initial")?,
            content: if keep_content != 0 {
                InitialContent::Preserve
            } else {
                InitialContent::Discard
            },
            final_state: crate::renderer::state(final_state, "final_state")?,
        };
        *out_id = on_graph(graph, |g| Ok(g.import_image(name, desc, import).0 .0))?;
        Ok(())
    })
}

/// Declares a buffer the graph creates.
///
/// # Safety
/// `name` is a NUL-terminated string; `out_id` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_create_buffer(
    graph: TgGraph,
    name: *const c_char,
    size_bytes: u64,
    out_id: *mut u32,
) -> TgStatus {
    boundary("tg_graph_create_buffer", || {
        // SAFETY: the caller's contract.
        let (name, out_id) = unsafe { (string(name, "name")?, out(out_id, "out_id")?) };
        if size_bytes == 0 {
            return Err(Failure::invalid("a buffer of 0 bytes"));
        }
        *out_id = on_graph(graph, |g| Ok(g.create_buffer(name, size_bytes).0 .0))?;
        Ok(())
    })
}

/// Keeps a resource after the frame (its passes are never pruned).
#[no_mangle]
pub extern "C" fn tg_graph_export(graph: TgGraph, resource: u32) -> TgStatus {
    boundary("tg_graph_export", || {
        on_graph(graph, |g| {
            let id = resource_id(g, resource, "resource")?;
            g.export(id.0);
            Ok(())
        })
    })
}

/// Declares a pass: raster (`raster` non-zero) or compute, of a TgPassClass.
///
/// # Safety
/// `name` is a NUL-terminated string; `out_pass` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_add_pass(
    graph: TgGraph,
    name: *const c_char,
    raster: u32,
    pass_class: u32,
    out_pass: *mut u32,
) -> TgStatus {
    boundary("tg_graph_add_pass", || {
        // SAFETY: the caller's contract.
        let (name, out_pass) = unsafe { (string(name, "name")?, out(out_pass, "out_pass")?) };
        let class = pass_class_of(pass_class)?;
        *out_pass = on_graph(graph, |g| {
            Ok(if raster != 0 {
                g.raster_pass(name, class, ()).id().0
            } else {
                g.compute_pass(name, class, ()).id().0
            })
        })?;
        Ok(())
    })
}

/// Declares compute pass `pass` async-capable: where the profile asks for async compute and
/// raster work can run beside it, the plan puts it on the async compute queue
/// (`tg_plan_submission`). It must write nothing but what it declares.
#[no_mangle]
pub extern "C" fn tg_pass_async_compute(graph: TgGraph, pass: u32) -> TgStatus {
    boundary("tg_pass_async_compute", || {
        on_graph(graph, |g| {
            let mut p = g.compute(PassId(pass)).ok_or_else(|| {
                Failure::invalid(format!("pass {pass} does not exist or is no compute pass"))
            })?;
            p.async_compute();
            Ok(())
        })
    })
}

/// Attaches a colour target to raster pass `pass`: cleared to `clear` (four floats) when
/// non-null, else loaded.
///
/// # Safety
/// `clear` is null or points to four floats.
#[no_mangle]
pub unsafe extern "C" fn tg_pass_color(
    graph: TgGraph,
    pass: u32,
    image: u32,
    clear: *const f32,
) -> TgStatus {
    boundary("tg_pass_color", || {
        // SAFETY: the caller's contract.
        let clear = unsafe { array(clear, if clear.is_null() { 0 } else { 4 }, "clear") }?;
        on_graph(graph, |g| {
            let image = resource_id(g, image, "image")?;
            let mut p = g
                .raster(PassId(pass))
                .ok_or_else(|| Failure::invalid(format!("pass {pass} is no raster pass")))?;
            match clear {
                [r, gr, b, a] => p.color_clear(image, ClearColor::Float([*r, *gr, *b, *a])),
                _ => p.color(image),
            };
            Ok(())
        })
    })
}

/// Attaches a depth target to raster pass `pass`: cleared to `*clear_depth` when non-null;
/// `read_only` non-zero: tested, not written.
///
/// # Safety
/// `clear_depth` is null or points to a float.
#[no_mangle]
pub unsafe extern "C" fn tg_pass_depth(
    graph: TgGraph,
    pass: u32,
    image: u32,
    clear_depth: *const f32,
    read_only: u32,
) -> TgStatus {
    boundary("tg_pass_depth", || {
        // SAFETY: the caller's contract.
        let clear = unsafe {
            array(
                clear_depth,
                usize::from(!clear_depth.is_null()),
                "clear_depth",
            )
        }?;
        on_graph(graph, |g| {
            let image = resource_id(g, image, "image")?;
            let mut p = g
                .raster(PassId(pass))
                .ok_or_else(|| Failure::invalid(format!("pass {pass} is no raster pass")))?;
            match (clear.first(), read_only != 0) {
                (Some(d), _) => p.depth_stencil_clear(
                    image,
                    ClearDepthStencil {
                        depth: *d,
                        stencil: 0,
                    },
                ),
                (None, true) => p.depth_stencil_read_only(image),
                (None, false) => p.depth_stencil(image),
            };
            Ok(())
        })
    })
}

/// Declares another use of `resource` by pass `pass` (a TgUse).
#[no_mangle]
pub extern "C" fn tg_pass_use(graph: TgGraph, pass: u32, resource: u32, use_kind: u32) -> TgStatus {
    boundary("tg_pass_use", || {
        on_graph(graph, |g| {
            let id = resource_id(g, resource, "resource")?;
            let bad_pass =
                || Failure::invalid(format!("pass {pass} does not exist or cannot {use_kind:?}"));
            if let Some(mut p) = g.raster(PassId(pass)) {
                match use_kind {
                    0 => p.sampled(id),
                    1 => p.storage_read(id.0),
                    2 => p.storage_write(id.0),
                    3 => p.storage_read_write(id.0),
                    4 => p.uniform(BufferId(id.0)),
                    5 => p.indirect(BufferId(id.0)),
                    6 => p.input(id),
                    _ => return Err(Failure::invalid(format!("use {use_kind} is no TgUse"))),
                };
                return Ok(());
            }
            let mut p = g.compute(PassId(pass)).ok_or_else(bad_pass)?;
            match use_kind {
                0 => p.sampled(id),
                1 => p.storage_read(id.0),
                2 => p.storage_write(id.0),
                3 => p.storage_read_write(id.0),
                4 => p.uniform(BufferId(id.0)),
                5 => p.indirect(BufferId(id.0)),
                6 => return Err(Failure::invalid("a compute pass has no input attachments")),
                _ => return Err(Failure::invalid(format!("use {use_kind} is no TgUse"))),
            };
            Ok(())
        })
    })
}

/// Compiles the graph for a profile ("adreno-7xx", "mali-valhall", "powervr-b",
/// "desktop-nvidia", "lavapipe", ...). The graph stays as declared: compile it again for
/// another profile.
///
/// # Safety
/// `profile` is a NUL-terminated string; `out_plan` is writable.
#[no_mangle]
pub unsafe extern "C" fn tg_graph_compile(
    graph: TgGraph,
    profile: *const c_char,
    out_plan: *mut TgPlan,
) -> TgStatus {
    boundary("tg_graph_compile", || {
        // SAFETY: the caller's contract.
        let (profile, out_plan) = unsafe {
            (
                optional_string(profile, "profile")?
                    .ok_or_else(|| Failure::new(TgStatus::NullPointer, "`profile` is null"))?,
                out(out_plan, "out_plan")?,
            )
        };
        let profiles = ProfileSet::from_env()?;
        let profile = profiles.get(profile)?;
        let plan = registry::with(graph.raw, Kind::Graph, "graph", |g: &GraphObject| {
            Ok(g.graph.clone().compile(profile)?.into_plan_and_payloads().0)
        })?;
        *out_plan = TgPlan {
            raw: registry::insert(Kind::Plan, PlanObject::new(plan))?,
        };
        Ok(())
    })
}
