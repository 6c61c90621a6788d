//! The `legwork` command. Everything it does lives in the library; `cli` only parses the
//! command line, calls the library and prints.

mod cli;

fn main() -> std::process::ExitCode {
    cli::main()
}
