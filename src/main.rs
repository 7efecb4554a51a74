//! The `furnace` binary: see `furnace --help`.

mod cli;

use clap::Parser;

fn main() {
    // `furnace … | head` closes stdout early; Rust's print macros then panic on the broken pipe.
    // Exit quietly with the conventional status 128 + SIGPIPE instead of a panic message.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.contains("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        default_hook(info);
    }));
    let cli = cli::Cli::parse();
    match cli::run(cli) {
        Ok(code) => std::process::exit(code),
        Err(f) => {
            eprintln!("error: {:#}", f.error);
            std::process::exit(f.code);
        }
    }
}
