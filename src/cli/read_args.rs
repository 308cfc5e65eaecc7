//! The arguments every command that reads one recording takes for what the file may not
//! say: its sample rate and the shaft speed. Declared once and flattened into `features`,
//! `import`, `inspect` and `replay`, so each reads them alike.

use crate::importers::ImportOptions;

/// `--sample-rate` and `--rpm`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct ReadArgs {
    /// Sample rate in Hz, for files that do not carry one (CSV); overrides the file and the
    /// rig file.
    #[arg(long)]
    pub sample_rate: Option<f64>,
    /// Shaft speed in rpm: a constant speed instead of the file's and the rig's speed source.
    #[arg(long)]
    pub rpm: Option<f64>,
}

impl ReadArgs {
    /// The importer options these arguments set.
    pub fn import_options(&self) -> ImportOptions {
        ImportOptions {
            sample_rate: self.sample_rate,
            rpm: self.rpm,
            ..Default::default()
        }
    }
}
