//! How a DAQ's channel list maps onto the rig: live adapters (serial, CAN) send the rig
//! file's `channels` in order; this splits them into the acceleration channels and the
//! analog tacho of a [`SampleBlock`](super::SampleBlock), applying each channel's
//! `sensitivity`.

use crate::config::{ChannelConfig, ChannelKind, SpeedConfig};

/// Where one device channel goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Slot {
    /// The k-th acceleration channel of the rig.
    Accel(usize),
    /// The analog tacho.
    Tacho,
    /// A channel the pipeline does not use (a second tacho channel).
    Unused,
}

/// The rig's channel order as a device sends it.
#[derive(Debug, Clone, PartialEq)]
pub struct RigLayout {
    pub slots: Vec<Slot>,
    /// Raw value x sensitivity = value in the channel's unit.
    pub sensitivity: Vec<f32>,
    pub names: Vec<String>,
    pub n_accel: usize,
    pub analog_tacho: bool,
}

impl RigLayout {
    /// The layout of the rig's `channels`; `speed` says which tacho channel is the one in use.
    pub fn new(channels: &[ChannelConfig], speed: &SpeedConfig) -> Self {
        let tacho_name = match speed {
            SpeedConfig::Tacho { channel, .. } => Some(channel.as_str()),
            _ => channels
                .iter()
                .find(|c| c.kind == ChannelKind::Tacho)
                .map(|c| c.name.as_str()),
        };
        let mut n_accel = 0;
        let mut analog_tacho = false;
        let slots = channels
            .iter()
            .map(|c| match c.kind {
                ChannelKind::Acceleration => {
                    n_accel += 1;
                    Slot::Accel(n_accel - 1)
                }
                ChannelKind::Tacho if Some(c.name.as_str()) == tacho_name && !analog_tacho => {
                    analog_tacho = true;
                    Slot::Tacho
                }
                ChannelKind::Tacho => Slot::Unused,
            })
            .collect();
        RigLayout {
            slots,
            sensitivity: channels.iter().map(|c| c.sensitivity as f32).collect(),
            names: channels.iter().map(|c| c.name.clone()).collect(),
            n_accel,
            analog_tacho,
        }
    }

    /// Channels a device must send.
    pub fn device_channels(&self) -> usize {
        self.slots.len()
    }

    /// Split device channels (rig order, raw values) into acceleration channels and the
    /// analog tacho, in engineering units.
    pub fn split(&self, device: Vec<Vec<f32>>) -> (Vec<Vec<f32>>, Option<Vec<f32>>) {
        let mut accel: Vec<Vec<f32>> = vec![Vec::new(); self.n_accel];
        let mut tacho = None;
        for ((mut v, slot), &s) in device.into_iter().zip(&self.slots).zip(&self.sensitivity) {
            if s != 1.0 {
                v.iter_mut().for_each(|x| *x *= s);
            }
            match *slot {
                Slot::Accel(k) => accel[k] = v,
                Slot::Tacho => tacho = Some(v),
                Slot::Unused => {}
            }
        }
        (accel, tacho)
    }

    /// The reverse of [`RigLayout::split`] for emulators: device channels (raw values) from
    /// acceleration channels and an analog tacho in engineering units.
    pub fn join(&self, accel: &[Vec<f32>], tacho: Option<&[f32]>, n: usize) -> Vec<Vec<f32>> {
        self.slots
            .iter()
            .zip(&self.sensitivity)
            .map(|(slot, &s)| {
                let v: &[f32] = match *slot {
                    Slot::Accel(k) => accel.get(k).map_or(&[][..], Vec::as_slice),
                    Slot::Tacho => tacho.unwrap_or(&[]),
                    Slot::Unused => &[],
                };
                let mut out: Vec<f32> = v
                    .iter()
                    .take(n)
                    .map(|x| if s != 1.0 { x / s } else { *x })
                    .collect();
                out.resize(n, 0.0);
                out
            })
            .collect()
    }

    /// "axial, vertical, horizontal, tacho" for messages.
    pub fn describe(&self) -> String {
        self.names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::RigConfig;
    use std::path::Path;

    #[test]
    fn lut_rig_sends_three_accelerations_and_a_tacho() {
        let rig = RigConfig::load(
            &Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/lut-rig.toml"),
        )
        .unwrap();
        let l = RigLayout::new(&rig.channels, &rig.speed);
        assert_eq!(
            l.slots,
            [Slot::Accel(0), Slot::Accel(1), Slot::Accel(2), Slot::Tacho]
        );
        let dev = l.join(&[vec![1.0], vec![2.0], vec![3.0]], Some(&[5.0]), 1);
        assert_eq!(dev, [[1.0], [2.0], [3.0], [5.0]]);
        let (a, t) = l.split(dev);
        assert_eq!(a, [[1.0], [2.0], [3.0]]);
        assert_eq!(t.unwrap(), [5.0]);
    }

    #[test]
    fn sensitivity_scales_raw_values() {
        let text = std::fs::read_to_string(
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("config/cwru-de.toml"),
        )
        .unwrap();
        let rig =
            RigConfig::parse(&text.replacen("unit = \"g\"", "unit = \"g\"\nsensitivity = 0.5", 1))
                .unwrap();
        let l = RigLayout::new(&rig.channels, &rig.speed);
        assert!(!l.analog_tacho);
        let dev = l.join(&[vec![1.0, 2.0], vec![3.0, 4.0], vec![]], None, 2);
        assert_eq!(dev, [vec![2.0, 4.0], vec![3.0, 4.0], vec![0.0, 0.0]]);
        assert_eq!(l.split(dev).0[0], [1.0, 2.0]);
    }
}
