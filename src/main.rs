//! The `furnace` binary: see `furnace --help`.

mod cli;

use clap::Parser;

fn main() {
    let cli = cli::Cli::parse();
    match cli::run(cli) {
        Ok(code) => std::process::exit(code),
        Err(f) => {
            eprintln!("error: {:#}", f.error);
            std::process::exit(f.code);
        }
    }
}
