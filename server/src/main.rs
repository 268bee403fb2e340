//! The `echogym` binary: see [`echogym::cli`].

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(echogym::cli::main_with_args(std::env::args_os()))
}
