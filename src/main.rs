//! The `raypack` command: parse, dispatch, map errors to exit codes.
//!
//! Exit codes: 0 success, 2 bad input (the message names file, line and key), 1 any
//! other failure, such as an output that cannot be written. The error chain is printed
//! once, as ripgrep does: each error's message leaves its cause to the chain.

mod cli;

use clap::Parser;
use std::process::ExitCode;

#[global_allocator]
static ALLOC: cli::huge_pages::HugePages = cli::huge_pages::HugePages;

fn main() -> ExitCode {
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        Err(e) => {
            // --help and --version are not failures.
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return ExitCode::from(code);
        }
    };
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("raypack: {e:#}");
            ExitCode::from(cli::exit_code(&e))
        }
    }
}
