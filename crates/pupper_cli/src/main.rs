//! The `pupper` binary: the CLI of `pupper_cli` with an embedded CPython.

fn main() -> std::process::ExitCode {
    std::process::ExitCode::from(pupper_cli::main(
        std::env::args_os(),
        pupper_cli::Host::Embedded {
            built_with: option_env!("PUPPER_BUILD_PYTHON"),
        },
    ))
}
