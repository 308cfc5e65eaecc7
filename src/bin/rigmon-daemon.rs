//! `rigmon-daemon`: the lean service binary systemd starts (`systemd/rigmon.service`). It runs
//! the monitoring daemon exactly as `rigmon run` does, with the same arguments, and names only
//! `rigmon_runtime` (on the core): no PostgreSQL client, no plotting, no simulator or trainer
//! is linked. It lives in the `rigmon` package so that `cargo build` and `cargo test` build it.

use clap::Parser;
use rigmon_runtime::run;

#[derive(Parser, Debug)]
#[command(
    name = "rigmon-daemon",
    version,
    about = "rigmon's monitoring daemon (the service binary; `rigmon run` takes the same arguments)"
)]
struct Cli {
    /// Log filter (e.g. info, debug, rigmon=debug); RUST_LOG works too.
    #[arg(long, default_value = "info")]
    log: String,
    #[command(flatten)]
    run: run::Args,
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    run::init_logging(&cli.log);
    match run::run(cli.run) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
