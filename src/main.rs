//! rigmon command line: parse and dispatch; each subcommand lives in `rigmon::cli`.

use clap::{Parser, Subcommand};
use rigmon::cli;

#[derive(Parser, Debug)]
#[command(
    name = "rigmon",
    version,
    about = "Condition monitoring for rotating machinery: DAQ -> envelope order spectra -> ONNX classifier -> health on Zenoh"
)]
struct Cli {
    /// Log filter (e.g. info, debug, rigmon=debug); RUST_LOG works too.
    #[arg(long, global = true, default_value = "info")]
    log: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Convert a recording (any-layout .mat, WAV, CSV) into a rigmon MCAP file.
    Import(cli::import::Args),
    /// Rewrite a damaged, cut or unfinished MCAP file as a clean one any MCAP reader opens.
    Repair(cli::repair::Args),
    /// Print envelope-order-spectrum features per window as JSON Lines.
    Features(cli::features::Args),
    /// Draw a recording's envelope order spectrum with fault-order markers (PNG).
    Inspect(cli::inspect::Args),
    /// RMS per window over a recording's life and the RMS 3-sigma rule's alarm (PNG).
    Trend(cli::trend::Args),
    /// Simulate the rig (rotor + ball bearing + defects) to MCAP or WAV.
    Simulate(cli::simulate::Args),
    /// Generate a labelled simulated dataset from a plan.
    Dataset(cli::dataset::Args),
    /// Fit the simulator to measured recordings (effects, error before/after, report).
    Calibrate(cli::calibrate::Args),
    /// Calibrate, simulate and train for one machine from its measured recordings; report.
    Adapt(cli::adapt::Args),
    /// Train the classifier on a simulated dataset and export ONNX.
    Train(cli::train::Args),
    /// Retrain the output layer on a fraction of labelled measured recordings.
    Finetune(cli::finetune::Args),
    /// Score a model on labelled recordings, whole-record.
    Evaluate(cli::evaluate::Args),
    /// Align a model to one machine's healthy recordings (reference levels; no training).
    Align(cli::align::Args),
    /// Model files: `stamp` one with the identity of the rig it was trained for.
    Model(cli::model::Args),
    /// 2-D t-SNE/PCA picture of feature windows by class and domain.
    Embed(cli::embed::Args),
    /// Run the monitoring daemon from a config file.
    Run(cli::run::Args),
    /// Replay a recording through the monitoring pipeline.
    Replay(cli::replay::Args),
    /// Print health messages from the network, one line each.
    Watch(cli::watch::Args),
    /// List the signals of an openDAQ streaming server (DewesoftX, SIRIUS): id, rate, unit.
    Devices(cli::devices::Args),
    /// Emulate a DAQ adapter (serial) streaming a recording.
    Emulate(cli::emulate::Args),
    /// Benchmarks with ratios against a baseline in the same run.
    Bench(cli::bench::Args),
    /// The fleet historian: health and status from the Zenoh mesh into PostgreSQL.
    Historian(cli::historian::Args),
    /// A point's stored history over Zenoh (from a historian): lines, JSON or a trend PNG.
    History(cli::history::Args),
    /// List state-change events (alarms) from the historian's database.
    Alarms(cli::alarms::ListArgs),
    /// Acknowledge an alarm: who and why.
    Ack(cli::alarms::AckArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    cli::run::init_logging(&cli.log);
    let result = match cli.command {
        Command::Import(a) => cli::import::refuse_overwrite(&a).and_then(|()| cli::import::run(a)),
        Command::Repair(a) => cli::repair::refuse_overwrite(&a).and_then(|()| cli::repair::run(a)),
        Command::Features(a) => cli::features::run(a),
        Command::Inspect(a) => {
            cli::inspect::refuse_overwrite(&a).and_then(|()| cli::inspect::run(a))
        }
        Command::Trend(a) => cli::trend::refuse_overwrite(&a).and_then(|()| cli::trend::run(a)),
        Command::Simulate(a) => {
            cli::simulate::refuse_overwrite(&a).and_then(|()| cli::simulate::run(a))
        }
        Command::Dataset(a) => {
            cli::dataset::refuse_overwrite(&a).and_then(|()| cli::dataset::run(a))
        }
        Command::Calibrate(a) => {
            cli::calibrate::refuse_overwrite(&a).and_then(|()| cli::calibrate::run(a))
        }
        Command::Adapt(a) => cli::adapt::refuse_overwrite(&a).and_then(|()| cli::adapt::run(a)),
        Command::Train(a) => cli::train::refuse_overwrite(&a).and_then(|()| cli::train::run(a)),
        Command::Finetune(a) => {
            cli::finetune::refuse_overwrite(&a).and_then(|()| cli::finetune::run(a))
        }
        Command::Evaluate(a) => {
            cli::evaluate::refuse_overwrite(&a).and_then(|()| cli::evaluate::run(a))
        }
        Command::Align(a) => cli::align::refuse_overwrite(&a).and_then(|()| cli::align::run(a)),
        Command::Model(a) => cli::model::run(a),
        Command::Embed(a) => cli::embed::refuse_overwrite(&a).and_then(|()| cli::embed::run(a)),
        Command::Run(a) => cli::run::run(a),
        Command::Replay(a) => cli::replay::run(a),
        Command::Watch(a) => cli::watch::run(a),
        Command::Devices(a) => cli::devices::run(a),
        Command::Emulate(a) => cli::emulate::run(a),
        Command::Bench(a) => cli::bench::run(a),
        Command::Historian(a) => cli::historian::run(a),
        Command::History(a) => cli::history::run(a),
        Command::Alarms(a) => cli::alarms::list(a),
        Command::Ack(a) => cli::alarms::ack(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
