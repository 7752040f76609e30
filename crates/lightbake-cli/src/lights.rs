//! The lights a command line changes: which are baked indirect only (`--lighting`,
//! `--indirect-only`) and the light groups (`--group`, else the glTF's extras).

use lightbake::settings::LightGroup;
use lightbake::{BakeSettings, ImportedScene};

use crate::{Args, CliError};

/// The `--lighting` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Lighting {
    /// Direct and indirect light.
    Full,
    /// Indirect light only: the lights stay real-time.
    Indirect,
}

/// Marks the lights `--lighting` / `--indirect-only` choose as baked indirect only.
pub(crate) fn choose_lighting(
    args: &Args,
    scene: &mut lightbake::scene::Scene,
) -> Result<(), CliError> {
    use lightbake::scene::LightBake;
    for name in &args.indirect_only {
        if !scene.lights.iter().any(|l| &l.name == name) {
            let names: Vec<&str> = scene.lights.iter().map(|l| l.name.as_str()).collect();
            return Err(format!(
                "--indirect-only: the scene has no light named '{name}' (its lights: {})",
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            )
            .into());
        }
    }
    for l in &mut scene.lights {
        if args.indirect_only.contains(&l.name)
            || (args.indirect_only.is_empty() && args.lighting == Lighting::Indirect)
        {
            l.bake = LightBake::IndirectOnly;
        }
    }
    Ok(())
}

/// `--group NAME=MEMBER,...` parsed.
pub(crate) fn parse_group(text: &str) -> Result<LightGroup, String> {
    LightGroup::parse(text).map_err(|e| e.to_string())
}

/// `settings` with the light groups: those of `--group` (already in `settings`), else those
/// the glTF's extras give (checked against the scene when the bake starts).
pub(crate) fn with_groups(
    mut settings: BakeSettings,
    args: &Args,
    imported: &ImportedScene,
) -> Result<BakeSettings, CliError> {
    if args.group.is_empty() {
        settings.groups = imported.light_groups.clone();
        settings.validate()?;
    }
    Ok(settings)
}
