//! A bake into a folder that holds an earlier bake's cache follows it: the cache is read
//! (a damaged, truncated, foreign or older one gives a one-line warning and a full bake), the
//! edit is found, and the bake recomputes what it changed (`lightbake::incremental`). A bake
//! writes its state after each split stage (`lightbake.partial`), so one that was killed, run
//! again on the same input, keeps the stages it finished.

use std::path::Path;

use lightbake::incremental::{self, Plan};
use lightbake::{BakeReport, BakeSettings, Scene};

/// How a bake of `scene` into `out` follows the cache there (`full`: it does not).
pub(crate) fn plan(out: &Path, scene: &Scene, settings: &BakeSettings, full: bool) -> Plan {
    let limit = settings.memory_budget_mib.saturating_mul(1 << 20);
    // A bake into OUT that was killed: the same input and settings resume it.
    match incremental::read_partial(out, limit) {
        Ok(Some(partial)) if !full => {
            let stages: Vec<String> = (partial.values.stages.iter())
                .map(|k| {
                    let share = k.finished_share();
                    if share < 1.0 {
                        format!("{} ({:.0}% of its items)", k.stage, 100.0 * share)
                    } else {
                        k.stage.to_string()
                    }
                })
                .collect();
            if let Some(plan) = incremental::resume(partial, scene, settings) {
                println!(
                    "resuming the bake into {} that stopped: the stages it finished are kept ({})",
                    out.display(),
                    stages.join(", ")
                );
                return plan;
            }
        }
        Err(why) => eprintln!("warning: {why}; the unfinished bake there is not resumed"),
        _ => {}
    }
    let previous = incremental::read_cache(out, limit);
    if let Err(why) = &previous {
        eprintln!("warning: {why}; every texel is baked");
    }
    incremental::plan(previous, scene, settings, full)
}

/// One line on what an incremental bake computed again, by split stage.
pub(crate) fn summary(report: &BakeReport) -> Option<String> {
    let inc = report.incremental.as_ref()?;
    if let Some(why) = &inc.full {
        return Some(format!(
            "incremental: full bake ({why}); a cache for the next bake into the folder is kept"
        ));
    }
    if inc.stages.is_empty() {
        // Relit from the cached light groups: no split stage ran.
        return Some(format!(
            "incremental: nothing lit again; {}",
            inc.layout.join("; ")
        ));
    }
    let stages: Vec<String> = (inc.stages.iter())
        .map(|s| {
            let share = s.computed as f64 / (s.items.max(1)) as f64;
            format!("{} {:.1}%", s.stage, 100.0 * share)
        })
        .collect();
    Some(format!(
        "incremental: {:.1}% of the split stages' items computed again ({}); {}",
        100.0 * inc.recomputed,
        stages.join(", "),
        inc.layout.join("; ")
    ))
}

/// Where a bake into `out` writes its state after each split stage (a failed write costs only
/// the resume: a warning, once).
pub(crate) fn checkpoints(out: &Path) -> lightbake::bake::Checkpoint {
    let out = out.to_path_buf();
    let warned = std::sync::atomic::AtomicBool::new(false);
    std::sync::Arc::new(move |cache| {
        if let Err(e) = incremental::write_partial(&out, cache)
            && !warned.swap(true, std::sync::atomic::Ordering::Relaxed)
        {
            eprintln!(
                "warning: cannot keep the bake's state in {}: {e}; a killed bake cannot resume",
                out.display()
            );
        }
    })
}

/// Removes the state a failed bake kept in `out` (and `out` itself when the bake made it and
/// left it empty).
pub(crate) fn discard_partial(out: &Path, existed: bool) {
    let partial = out.join(incremental::PARTIAL_FILE);
    if std::fs::symlink_metadata(&partial).is_ok_and(|m| m.is_file()) {
        let _ = std::fs::remove_file(&partial);
    }
    if !existed {
        let _ = std::fs::remove_dir(out);
    }
}
