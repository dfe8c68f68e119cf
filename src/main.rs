//! The `septa` binary: see `septa --help`.

mod cli;

/// Running out of memory is an error message and exit status 2, not an abort.
#[global_allocator]
static ALLOCATOR: septa::memory::ClearOutOfMemory = septa::memory::ClearOutOfMemory;

fn main() -> std::process::ExitCode {
    cli::main()
}
