//! `bake convergence`: the convergence study of every method, written as CSV, Markdown and
//! plots.

use super::*;
use lightbake::analysis::study::{StudyRow, StudySize, run_study};
use lightbake::atomic::StagedFiles;

/// Runs the study of `args` and writes its files.
pub(super) fn run(args: ConvergenceArgs) -> Result<(), CliError> {
    let mut settings = BakeSettings::medium();
    settings.threads = args.threads;
    if let Some(d) = args.texel_density {
        settings.layout.texel_density = Some(d);
        settings.layout.texel_density_from_scene = false;
    }
    settings.validate()?;
    let imported = import_gltf_with(
        &args.scene,
        &import_options(&settings, args.light_convention, &args.allow_read),
    )?;
    let size = if args.quick {
        StudySize::Quick
    } else {
        StudySize::Full
    };
    println!(
        "convergence study of {} (reference bake first)",
        args.scene.display()
    );
    println!(
        "{:<20} {:>12} {:>9} {:>10} {:>10}",
        "curve", "budget", "time", "measured", "estimated"
    );
    let study = run_study(&imported.scene, &settings, size, |r: &StudyRow| {
        println!(
            "{:<20} {:>12} {:>8.3}s {:>9.3}% {:>10}",
            r.curve,
            format!("{}={}", r.parameter, r.budget),
            r.seconds,
            100.0 * r.measured,
            r.estimated
                .map_or("-".into(), |e| format!("{:.3}%", 100.0 * e))
        );
    })?;
    let mut csv = String::from(StudyRow::CSV_HEADER);
    csv.push('\n');
    for r in &study.rows {
        csv.push_str(&r.csv());
        csv.push('\n');
    }
    let (svg, png) = plot::render(&study)?;
    let mut files = StagedFiles::new(&args.output);
    let out = &args.output;
    let stage = |files: &mut StagedFiles, name: &str, bytes: &[u8]| {
        files
            .stage(&out.join(name), bytes)
            .map_err(|e| e.to_string())
    };
    stage(&mut files, "convergence.csv", csv.as_bytes())?;
    stage(&mut files, "convergence.md", study.markdown().as_bytes())?;
    stage(&mut files, "convergence.svg", &svg)?;
    stage(&mut files, "convergence.png", &png)?;
    let written = files.commit()?;
    println!();
    print!("{}", study.markdown());
    println!("wrote {} files to {}", written.len(), out.display());
    Ok(())
}
