//! The `echogym` binary: see [`echogym::cli`].

fn main() -> std::process::ExitCode {
    echogym::cli::main_with_args(std::env::args_os())
}
