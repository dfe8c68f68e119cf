//! The `septa` binary: see `septa --help`.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
