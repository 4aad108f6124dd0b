//! Harness for GPU end-to-end tests: every context runs with the Khronos validation layer and
//! synchronization validation and the best-practices checks, and [`Gpu`] fails the test on any
//! message the layer reported (but the reviewed `tilegraph_vk::SILENCED` ones).

use tilegraph_vk::{Context, ContextOptions, FeatureRequest, Validation, VkError};

/// A validated context for one test. Dropping it checks validation: any warning or error the
/// layer reported during the test, or when the device was destroyed (objects the test leaked),
/// panics (fails) the test, naming the messages.
pub struct Gpu {
    ctx: Option<Context>,
}

impl Gpu {
    /// A context checked at its end (see [`Gpu`]).
    pub fn new(ctx: Context) -> Self {
        Gpu { ctx: Some(ctx) }
    }
}

impl std::ops::Deref for Gpu {
    type Target = Context;
    fn deref(&self) -> &Context {
        self.ctx
            .as_ref()
            .expect("the context lives until the Gpu is dropped")
    }
}

impl Drop for Gpu {
    fn drop(&mut self) {
        let Some(ctx) = self.ctx.take() else {
            return;
        };
        if std::thread::panicking() {
            return;
        }
        if let Err(e) = ctx.wait_idle().and_then(|_| ctx.destroy_checked()) {
            panic!("Vulkan validation failed the test: {e}");
        }
    }
}

pub fn init_logging() {
    let _ = env_logger::builder().is_test(true).try_init();
}

/// Context options for tests: validation required, the named profile forced (or the detected one
/// when `None`), and the given features on top of the executor's.
pub fn options(profile: Option<&str>, features: FeatureRequest) -> ContextOptions {
    let mut o = ContextOptions::from_env();
    o.validation = Validation::Required;
    if let Some(p) = profile {
        o.profile = Some(p.to_string());
    }
    o.features.required.extend(features.required);
    o.features.optional.extend(features.optional);
    o
}

/// A validated context on the default device (lavapipe in CI), optionally forcing a profile.
pub fn gpu(profile: Option<&str>) -> Result<Gpu, VkError> {
    init_logging();
    Ok(Gpu::new(Context::new(options(
        profile,
        FeatureRequest::default(),
    ))?))
}

/// Every device feature the culling techniques use (two-phase HiZ's visibility buffer oracle,
/// GPU draw counts, occlusion queries, conditional rendering, raster occlusion's flags).
pub fn culling_features() -> FeatureRequest {
    FeatureRequest::default().require([
        tilegraph_vk::Feature::GeometryShader,
        tilegraph_vk::Feature::DrawIndirectCount,
        tilegraph_vk::Feature::MultiDrawIndirect,
        tilegraph_vk::Feature::HostQueryReset,
        tilegraph_vk::Feature::ConditionalRendering,
        tilegraph_vk::Feature::FragmentStoresAndAtomics,
    ])
}

/// Same as [`gpu`] with extra features.
pub fn gpu_with(profile: Option<&str>, features: FeatureRequest) -> Result<Gpu, VkError> {
    init_logging();
    Ok(Gpu::new(Context::new(options(profile, features))?))
}

pub mod engine;
pub mod frames;

/// `$TILEGRAPH_TEST_DATA` or `../shared/data` beside the repository.
pub fn test_data_dir() -> std::path::PathBuf {
    std::env::var_os("TILEGRAPH_TEST_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
        })
}

/// A file of the test data, if the data directory is there.
pub fn test_data(relative: &str) -> Option<std::path::PathBuf> {
    let p = test_data_dir().join(relative);
    p.exists().then_some(p)
}
pub mod golden;
