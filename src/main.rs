//! The `sightline` command-line program: scene statistics, OBJ export, camera paths,
//! rendering single frames and walkthroughs, the culling benchmark, merging the shards of a
//! walk, the lab's charts and the CSG demo. Every error is one line on stderr: exit code 2
//! for a usage error, 1 for a failure.

#![forbid(unsafe_code)]

mod cli;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let args = match cli::Cli::try_parse() {
        Ok(args) => args,
        // Help and version go to stdout as clap prints them; with no command at all the
        // help goes, whole, to stderr with exit code 2.
        Err(e) if !e.use_stderr() || e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            e.exit()
        }
        Err(e) => {
            eprintln!("{}", one_line(&e.render().to_string()));
            return ExitCode::from(2);
        }
    };
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

/// A clap error as one line: its message lines joined, without the usage block and the
/// pointer to `--help` that clap adds.
fn one_line(text: &str) -> String {
    let lines = text.lines().map(str::trim).take_while(|l| !l.starts_with("Usage:"));
    let kept: Vec<&str> = lines.filter(|l| !l.is_empty() && !l.starts_with("For more information")).collect();
    kept.join(" ")
}
