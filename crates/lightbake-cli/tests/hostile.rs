//! The hostile-input suite (see `hostile/mod.rs`): every crafted input bakes or is refused
//! in one line, and nothing outside the scene's folder reaches the outputs.

#[path = "hostile_cases/mod.rs"]
mod hostile;

use hostile::{Case, cases, outputs, run_all, split};

fn check(cases: Vec<Case>) {
    let reports = run_all(&cases);
    let failed: Vec<String> = reports
        .iter()
        .filter_map(|r| r.problem.as_ref().map(|p| format!("{}: {p}", r.name)))
        .collect();
    let behaved = reports.iter().filter(|r| r.outcome.behaved()).count();
    println!(
        "{behaved} of {} behaved, {} failed",
        reports.len(),
        failed.len()
    );
    assert!(
        failed.is_empty(),
        "{} case(s) failed:\n{}",
        failed.len(),
        failed.join("\n")
    );
}

#[test]
fn reads_stay_inside_the_scene_folder() {
    check(cases::file_access());
}

#[test]
fn counts_are_checked_before_allocating() {
    check(cases::counts());
}

#[test]
fn node_graphs_and_lights_are_bounded() {
    check(cases::graphs());
}

#[test]
fn malformed_files_are_refused() {
    check(cases::malformed());
}

#[test]
fn split_bake_files_are_checked() {
    check(split::cases());
}

#[test]
fn writes_stay_inside_the_output_folder() {
    check(outputs::cases());
}

/// The large cases: a flat floor of 40 000 and 10⁶ triangles, a curved one, a 10⁶-triangle
/// soup, 10⁵ point lights, 20 000 instances. Minutes in release:
/// `LIGHTBAKE_HOSTILE_BIN=target/release/bake cargo test -p lightbake-cli --test hostile -- --ignored`.
#[test]
#[ignore]
fn large_inputs_bake_in_proportion() {
    check(cases::large());
}
