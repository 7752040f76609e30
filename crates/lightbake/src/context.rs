//! The bake context: what every lighting pass reads — the unwrapped scene, its layout, the
//! ray-tracing structure, the validated texel patches, the settings and the plan — and
//! [`Prepared`], which makes one without running the lighting passes (for the core's tests,
//! the benchmarks and the studies).

use crate::bvh::RayScene;
use crate::error::Result;
use crate::plan::BakePlan;
use crate::raster::Patches;
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::stage::Stage;
use crate::unwrap::{Layout, unwrap_scene};

/// What every lighting pass reads: the unwrapped scene, its layout, the ray-tracing structure,
/// the texel patches, the settings and the plan.
#[derive(Clone, Copy)]
pub struct BakeContext<'a> {
    /// The unwrapped scene ([`Layout::apply`]).
    pub scene: &'a Scene,
    /// Lightmap layout.
    pub layout: &'a Layout,
    /// Ray queries.
    pub rays: &'a RayScene,
    /// Texel patches (validated).
    pub patches: &'a Patches,
    /// Settings.
    pub settings: &'a BakeSettings,
    /// The plan.
    pub plan: &'a BakePlan,
}

/// A scene made ready for lighting passes, without running them: plan, unwrap (with the
/// density that follows the light), BVH, texel patches (validated). For tests, benchmarks
/// and studies that drive the passes themselves.
pub struct Prepared {
    /// The unwrapped scene.
    pub scene: Scene,
    /// Its layout.
    pub layout: Layout,
    /// Ray queries.
    pub rays: RayScene,
    /// Texel patches.
    pub patches: Patches,
    /// Settings.
    pub settings: BakeSettings,
    /// The plan.
    pub plan: BakePlan,
}

impl Prepared {
    /// Plans, unwraps, builds the BVH and the validated patches of `scene`.
    ///
    /// # Errors
    /// As [`crate::bake()`] for the stages it runs.
    pub fn new(scene: &Scene, settings: &BakeSettings) -> Result<Self> {
        settings.validate()?;
        scene.validate()?;
        let plan = BakePlan::new(scene, settings);
        let mut layout = unwrap_scene(scene, settings, plan.texel_density)?;
        // The same triangles as the unwrapped scene's.
        let rays = RayScene::build(scene);
        if plan.runs(Stage::Density) {
            // Where the pilot finds nothing to adapt to, the density stays uniform, as in a
            // bake.
            if let Ok((adapted, _)) = crate::density::adapt(scene, settings, &plan, &layout, &rays)
            {
                layout = adapted;
            }
        }
        let baked = layout.apply(scene);
        let mut patches = Patches::build(&baked, &layout, &rays);
        patches.fix_validity(&baked, &layout, &rays);
        Ok(Self {
            scene: baked,
            layout,
            rays,
            patches,
            settings: settings.clone(),
            plan,
        })
    }

    /// The context the lighting passes read.
    pub fn ctx(&self) -> BakeContext<'_> {
        BakeContext {
            scene: &self.scene,
            layout: &self.layout,
            rays: &self.rays,
            patches: &self.patches,
            settings: &self.settings,
            plan: &self.plan,
        }
    }
}
