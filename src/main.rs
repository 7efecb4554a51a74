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
            furnace::io::process::kill_all();
            furnace::io::cleanup::remove_all();
            std::process::exit(141);
        }
        default_hook(info);
    }));
    let cli = cli::Cli::parse();
    // Ctrl-C or SIGTERM: kill the renderers and model servers still running, with what they
    // started (io::process), remove the temporary files and folders still alive (io::cleanup), then
    // exit with the conventional 128 + SIGINT. Outputs are renamed into place, so none is torn.
    let _ = ctrlc::set_handler(|| {
        furnace::io::process::kill_all();
        furnace::io::cleanup::remove_all();
        std::process::exit(130);
    });
    match cli::run(cli) {
        Ok(code) => std::process::exit(code),
        Err(f) => {
            // user input quoted in an error is bounded where it is quoted; this bounds the rest
            let text = cli::error_text(&f.error);
            let cut: String = text.chars().take(4000).collect();
            let more = if cut.len() < text.len() { " …" } else { "" };
            eprintln!("error: {cut}{more}");
            std::process::exit(f.code);
        }
    }
}
