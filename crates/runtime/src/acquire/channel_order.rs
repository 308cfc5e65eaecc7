//! Which of a recording's channels feeds each rig acceleration channel (by name, exact then
//! ignoring case), for the in-memory and the streamed file replay alike.

use crate::config::RigConfig;
use anyhow::{bail, Result};

/// Where each rig acceleration channel is among a recording's channels `names` (exact name,
/// then ignoring case; None: absent, replayed as NaN), and the absent ones' names. Warns when the rig states another
/// sample rate than the recording's `fs` and about absent channels; the classifier channel
/// absent is an error. `what` names the recording in the messages.
pub(crate) fn rig_channel_order(
    rig: &RigConfig,
    names: &[&str],
    fs: f64,
    what: &str,
) -> Result<(Vec<Option<usize>>, Vec<String>)> {
    if let Some(rig_fs) = rig.acquisition.sample_rate_hz {
        if (rig_fs - fs).abs() > 1e-6 * rig_fs {
            tracing::warn!(
                "{what} is sampled at {fs} Hz but rig {} says acquisition.sample_rate_hz = {rig_fs}; replaying at the recording's rate",
                rig.machine.id
            );
        }
    }
    let mut order = Vec::new();
    let mut absent = Vec::new();
    for ch in rig.acceleration_channels() {
        let idx = names
            .iter()
            .position(|n| *n == ch.name)
            .or_else(|| names.iter().position(|n| n.eq_ignore_ascii_case(&ch.name)));
        if idx.is_none() {
            absent.push(ch.name.clone());
        }
        order.push(idx);
    }
    if let Some(cls) = rig.classifier_channel() {
        if absent.contains(&cls.name) {
            bail!(
                "{what} has no channel {:?} (the classifier channel of rig {}); it has {names:?}. Rename the rig channel or pick another `features.classifier_axis`",
                cls.name,
                rig.machine.id
            );
        }
    }
    if !absent.is_empty() {
        tracing::warn!("{what} has no channel(s) {absent:?} of rig {} (it has {names:?}); they are replayed as NaN", rig.machine.id);
    }
    Ok((order, absent))
}
