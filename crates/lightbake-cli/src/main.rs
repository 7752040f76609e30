//! The `bake` binary; see the crate's library for the command.

fn main() -> std::process::ExitCode {
    lightbake_cli::main()
}
