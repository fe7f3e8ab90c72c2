//! The `sightline` command-line program: scene statistics, OBJ export, camera paths,
//! rendering single frames and walkthroughs, and the culling benchmark.

#![forbid(unsafe_code)]

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    if let Some(why) = args.usage_error() {
        eprintln!("error: {why}");
        return ExitCode::from(2);
    }
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One clear line, the whole cause chain.
            let mut msg = format!("error: {e}");
            let mut src = e.source();
            while let Some(s) = src {
                // Some errors print their cause in their own message already: say it once.
                let text = s.to_string();
                if !msg.contains(&text) {
                    msg.push_str(&format!(": {text}"));
                }
                src = s.source();
            }
            eprintln!("{msg}");
            ExitCode::FAILURE
        }
    }
}
