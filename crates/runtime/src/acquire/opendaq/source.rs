//! `[source] type = "opendaq"`: a live source reading an openDAQ LT streaming server
//! (DewesoftX, SIRIUS/KRYPTON with openDAQ, the SDK's reference device). It subscribes the
//! signals the `[source.signals]` map names, turns every packet's time stamp into a
//! sample-clock index from the signal's own time domain, aligns the channels, and hands on
//! [`SampleBlock`](crate::acquire::SampleBlock)s. A lost server is reported as
//! `connected: false` and reconnected with backoff; damaged packets are counted and
//! skipped.

use super::aligner::Aligner;
use super::browse::list_signals;
use super::connection::Endpoint;
use super::protocol::Event;
use super::session::{Pumped, Session};
use super::signal::SignalDescription;
use crate::acquire::layout::RigLayout;
use crate::acquire::serial::{Throttle, RECONNECT_FIRST};
use crate::acquire::{
    offer_block, sleep_unless_stopped, BlockAssembler, BlockSender, Source, SourceStats, StopToken,
};
use crate::config::RigConfig;
use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::collections::HashMap;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn default_block_ms() -> f64 {
    100.0
}
fn default_reconnect_max_ms() -> u64 {
    2000
}
fn default_timeout_ms() -> u64 {
    3000
}
fn default_max_lag_ms() -> f64 {
    1000.0
}

/// `[source] type = "opendaq"`.
///
/// ```toml
/// [source]
/// type = "opendaq"
/// connection = "daq.lt://127.0.0.1:7414"
/// [source.signals]          # rig channel -> openDAQ signal (id or its last segment)
/// vertical = "AI0"
/// tacho = "AI1"
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpendaqSourceConfig {
    /// `daq.lt://HOST[:PORT][/PATH]`: the server's LT (WebSocket) streaming port, 7414 by
    /// default.
    pub connection: String,
    /// Rig channel name -> openDAQ signal id (or the id's last segment, e.g. `AI0`). Rig
    /// channels left out arrive as NaN (listed as absent).
    pub signals: BTreeMap<String, String>,
    /// Used only when the server cannot be reached at start-up: the sample rate to run at
    /// until it can (default: the rig's `acquisition.sample_rate_hz`). Otherwise the rate
    /// comes from the signals' time domain.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_rate_hz: Option<f64>,
    /// Block length handed downstream, ms.
    #[serde(default = "default_block_ms")]
    pub block_ms: f64,
    /// Longest wait between reconnection attempts, ms (the wait doubles from 50 ms).
    #[serde(default = "default_reconnect_max_ms")]
    pub reconnect_max_ms: u64,
    /// Connect/handshake/subscribe timeout, and how long a silent stream is tolerated, ms.
    #[serde(default = "default_timeout_ms")]
    pub timeout_ms: u64,
    /// A channel this far behind the others is padded with NaN (counted lost), ms.
    #[serde(default = "default_max_lag_ms")]
    pub max_lag_ms: f64,
}

impl OpendaqSourceConfig {
    /// A connection and signal map with the defaults.
    pub fn new(connection: impl Into<String>, signals: BTreeMap<String, String>) -> Self {
        OpendaqSourceConfig {
            connection: connection.into(),
            signals,
            sample_rate_hz: None,
            block_ms: default_block_ms(),
            reconnect_max_ms: default_reconnect_max_ms(),
            timeout_ms: default_timeout_ms(),
            max_lag_ms: default_max_lag_ms(),
        }
    }

    pub fn build(&self, rig: &RigConfig) -> Result<Box<dyn Source>> {
        Ok(Box::new(self.source(rig)?))
    }

    /// Check the settings against the rig and learn the sample rate from the server (or,
    /// when it cannot be reached now, from `sample_rate_hz` / the rig).
    pub fn source(&self, rig: &RigConfig) -> Result<OpendaqSource> {
        let endpoint = Endpoint::parse(&self.connection)?;
        if self.signals.is_empty() {
            bail!("opendaq source: `[source.signals]` is empty; map rig channels to openDAQ signals, e.g. vertical = \"AI0\" (`rigmon devices {}` lists them)", self.connection);
        }
        for name in self.signals.keys() {
            if !rig.channels.iter().any(|c| &c.name == name) {
                bail!(
                    "opendaq source: [source.signals] names {name:?}, which is not a rig channel ({})",
                    rig.channels.iter().map(|c| c.name.as_str()).collect::<Vec<_>>().join(", ")
                );
            }
        }
        if !(self.block_ms.is_finite() && (1.0..=10_000.0).contains(&self.block_ms)) {
            bail!(
                "opendaq source: block_ms = {} must be between 1 and 10000",
                self.block_ms
            );
        }
        if self.reconnect_max_ms < 50 {
            bail!(
                "opendaq source: reconnect_max_ms = {} must be at least 50",
                self.reconnect_max_ms
            );
        }
        if self.timeout_ms < 100 {
            bail!(
                "opendaq source: timeout_ms = {} must be at least 100",
                self.timeout_ms
            );
        }
        if !(self.max_lag_ms.is_finite() && self.max_lag_ms >= 1.0) {
            bail!(
                "opendaq source: max_lag_ms = {} must be at least 1",
                self.max_lag_ms
            );
        }
        let layout = RigLayout::new(&rig.channels, &rig.speed);
        let timeout = Duration::from_millis(self.timeout_ms);
        let fs = match server_rate(&endpoint, self.signals.values(), timeout) {
            Ok(fs) => fs,
            Err(e) => {
                let fs = match crate::acquire::live_sample_rate(self.sample_rate_hz, &rig.acquisition, "opendaq") {
                    Ok(fs) => fs,
                    Err(_) => return Err(e.context(
                        "opendaq source: the server cannot tell the sample rate now; set `sample_rate_hz` in [source] to start without it",
                    )),
                };
                tracing::warn!(
                    "opendaq {endpoint}: {e:#}; starting at {fs} Hz (from the configuration) and waiting for the server"
                );
                fs
            }
        };
        let units: HashMap<String, String> = rig
            .channels
            .iter()
            .map(|c| (c.name.clone(), c.unit.to_string()))
            .collect();
        // Device channel (rig order) -> aligner channel, for mapped channels.
        let mut mapped = Vec::new();
        for (i, name) in layout.names.iter().enumerate() {
            if let Some(sig) = self.signals.get(name) {
                mapped.push((i, sig.clone()));
            }
        }
        Ok(OpendaqSource {
            cfg: self.clone(),
            endpoint,
            fs,
            block: BlockAssembler::samples_for_ms(fs, self.block_ms),
            layout,
            mapped,
            units,
        })
    }
}

/// Sample rate of the mapped signals, from their time domains; an error when they differ.
fn server_rate<'a>(
    endpoint: &Endpoint,
    names: impl Iterator<Item = &'a String>,
    timeout: Duration,
) -> Result<f64> {
    let s = Session::start(endpoint, timeout)?;
    let ids = names.map(|n| s.resolve(n)).collect::<Result<Vec<_>>>()?;
    s.conn.close();
    let found = list_signals(endpoint, Some(&ids), timeout)?;
    let mut rate: Option<(f64, &str)> = None;
    for id in &ids {
        let info = found.signals.iter().find(|x| &x.id == id);
        let Some(info) = info.filter(|i| i.kind == "waveform") else {
            bail!(
                "opendaq source: signal {id} is {}; rigmon reads explicit scalar signals with a linear time domain",
                info.map_or("not described by the server".to_string(), |i| format!("of kind {} ({})", i.kind, i.data_type))
            );
        };
        let Some(r) = info.sample_rate_hz else {
            bail!("opendaq source: signal {id} has no linear time domain with a resolution, so it has no sample rate");
        };
        match rate {
            Some((r0, id0)) if (r - r0).abs() > 1e-9 * r0 => bail!(
                "opendaq source: signals run at different rates: {id0} at {r0} Hz, {id} at {r} Hz; map signals of one rate (set the device's channels to one sample rate)"
            ),
            _ => rate = Some((r, id)),
        }
    }
    rate.map(|(r, _)| r)
        .ok_or_else(|| anyhow::anyhow!("no signals"))
}

/// An openDAQ source ready to run.
#[derive(Debug)]
pub struct OpendaqSource {
    cfg: OpendaqSourceConfig,
    endpoint: Endpoint,
    fs: f64,
    block: usize,
    layout: RigLayout,
    /// (rig channel index, configured signal name)
    mapped: Vec<(usize, String)>,
    units: HashMap<String, String>,
}

/// Per mapped channel, what the current connection knows.
#[derive(Debug, Clone, Default)]
struct Bound {
    signo: Option<u32>,
    desc: Option<SignalDescription>,
}

/// A time domain's latest start: (table index, ticks) and delta.
#[derive(Debug, Clone, Copy)]
struct Domain {
    index: u64,
    ticks: i128,
    delta: i64,
}

/// State kept across connections: the sample clock origin (ticks) and tick size, so a
/// reconnection continues the same clock and its gap is measured.
#[derive(Debug, Default)]
struct Clock {
    origin: Option<i128>,
    delta: i64,
}

impl OpendaqSource {
    /// Rig channels that are not mapped (NaN in every block).
    fn unmapped(&self) -> Vec<String> {
        self.layout
            .names
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.mapped.iter().any(|(m, _)| m == i))
            .map(|(_, n)| n.clone())
            .collect()
    }
}

impl Source for OpendaqSource {
    fn describe(&self) -> String {
        format!(
            "opendaq {} @ {} Hz, {}",
            self.endpoint,
            self.fs,
            self.mapped
                .iter()
                .map(|(i, s)| format!("{} = {s}", self.layout.names[*i]))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }

    fn analog_tacho(&self) -> bool {
        self.layout.analog_tacho
    }

    fn sample_rate(&self) -> f64 {
        self.fs
    }

    fn absent_channels(&self) -> Vec<String> {
        self.unmapped()
    }

    fn run(
        self: Box<Self>,
        tx: BlockSender,
        stats: Arc<SourceStats>,
        stop: StopToken,
    ) -> Result<()> {
        let max_wait = Duration::from_millis(self.cfg.reconnect_max_ms);
        let timeout = Duration::from_millis(self.cfg.timeout_ms);
        let mut wait = RECONNECT_FIRST;
        let mut connected_before = false;
        let mut trouble = Throttle::default();
        let mut clock = Clock::default();
        let max_lag = BlockAssembler::samples_for_ms(self.fs, self.cfg.max_lag_ms);
        let mut aligner = Aligner::new(self.mapped.len(), max_lag);
        let mut asm = BlockAssembler::new(
            self.fs,
            self.layout.n_accel,
            self.layout.analog_tacho,
            self.block,
        );
        let mut seen_lost = 0u64;
        while !stop.is_stopped() {
            match self.connect(timeout) {
                Ok(mut session) => {
                    if connected_before {
                        SourceStats::add(&stats.reconnects, 1);
                        tracing::info!("opendaq {}: reconnected", self.endpoint);
                    } else {
                        tracing::info!("opendaq {}: streaming {}", self.endpoint, self.describe());
                    }
                    connected_before = true;
                    wait = RECONNECT_FIRST;
                    stats.connected.store(true, Ordering::Relaxed);
                    aligner.reset();
                    let why = self.stream(
                        &mut session,
                        &tx,
                        &stats,
                        &stop,
                        &mut clock,
                        &mut aligner,
                        &mut asm,
                        &mut seen_lost,
                        timeout,
                    );
                    stats.connected.store(false, Ordering::Relaxed);
                    asm.close();
                    for b in asm.take_ready() {
                        if !offer_block(&tx, b, &stats) {
                            return Ok(());
                        }
                    }
                    match why {
                        None => break,
                        Some(why) => {
                            tracing::warn!("opendaq {}: {why}; reconnecting", self.endpoint)
                        }
                    }
                }
                Err(e) => trouble.warn(|| {
                    format!(
                        "opendaq {}: {e:#}; retrying every {} ms at most",
                        self.endpoint,
                        max_wait.as_millis()
                    )
                }),
            }
            if !sleep_unless_stopped(wait, &stop) {
                break;
            }
            wait = (wait * 2).min(max_wait);
        }
        stats.connected.store(false, Ordering::Relaxed);
        asm.close();
        for b in asm.take_ready() {
            offer_block(&tx, b, &stats);
        }
        Ok(())
    }
}

impl OpendaqSource {
    /// Open a session and subscribe the mapped signals.
    fn connect(&self, timeout: Duration) -> Result<(Session, Vec<String>)> {
        let mut s = Session::start(&self.endpoint, timeout)?;
        let ids = self
            .mapped
            .iter()
            .map(|(_, n)| s.resolve(n))
            .collect::<Result<Vec<_>>>()?;
        let mut unique = ids.clone();
        unique.sort();
        unique.dedup();
        s.subscribe(&unique, timeout)?;
        Ok((s, ids))
    }

    /// Stream until stopped (`None`) or the connection is lost (`Some(reason)`).
    #[allow(clippy::too_many_arguments)]
    fn stream(
        &self,
        (session, ids): &mut (Session, Vec<String>),
        tx: &BlockSender,
        stats: &SourceStats,
        stop: &StopToken,
        clock: &mut Clock,
        aligner: &mut Aligner,
        asm: &mut BlockAssembler,
        seen_lost: &mut u64,
        timeout: Duration,
    ) -> Option<String> {
        let max_lag = BlockAssembler::samples_for_ms(self.fs, self.cfg.max_lag_ms);
        let mut bound: Vec<Bound> = vec![Bound::default(); ids.len()];
        let mut domains: HashMap<u32, Domain> = HashMap::new();
        let mut problem: Option<String> = None;
        let mut misfit = Throttle::default();
        let mut last_data = Instant::now();
        let mut bad_local = 0u64;
        let mut seen_bad = 0u64;
        let fs = self.fs;
        // (signal number, first table index, start and length in `values`), reused.
        let mut events: Vec<(u32, u64, usize, usize)> = Vec::new();
        let mut values: Vec<f64> = Vec::new();
        let mut described = Vec::new();
        loop {
            if stop.is_stopped() {
                return None;
            }
            events.clear();
            values.clear();
            described.clear();
            let mut gone: Option<String> = None;
            let pumped = session.pump(Duration::from_millis(100), &mut |e| match e {
                Event::Values {
                    signo,
                    first_index,
                    values: v,
                } => {
                    let at = values.len();
                    values.extend_from_slice(v);
                    events.push((signo, first_index, at, v.len()));
                }
                Event::LinearStart {
                    signo,
                    index,
                    value,
                } => {
                    domains
                        .entry(signo)
                        .and_modify(|d| {
                            d.index = index;
                            d.ticks = value;
                        })
                        .or_insert(Domain {
                            index,
                            ticks: value,
                            delta: 0,
                        });
                }
                Event::Described { signo } => described.push(signo),
                Event::Unavailable(v) => {
                    if let Some(id) = v.iter().find(|id| ids.contains(id)) {
                        gone = Some(format!("the server made {id} unavailable"));
                    }
                }
                Event::Unsubscribed { signo } if bound.iter().any(|b| b.signo == Some(signo)) => {
                    gone = Some(format!("the server unsubscribed signal number {signo}"));
                }
                Event::Desync(why) => gone = Some(format!("stream out of step ({why})")),
                _ => {}
            });
            match pumped {
                Pumped::Closed(why) => return Some(why),
                Pumped::Idle => {
                    if last_data.elapsed() > timeout {
                        return Some(format!("no data for {} ms", timeout.as_millis()));
                    }
                }
                Pumped::Message => {}
            }
            for &signo in &described {
                let Some((id, Some(desc))) = session.decoder.signal(signo) else {
                    continue;
                };
                for (k, want) in ids.iter().enumerate() {
                    if want == id {
                        bound[k] = Bound {
                            signo: Some(signo),
                            desc: Some(desc.clone()),
                        };
                        let rig_name = &self.layout.names[self.mapped[k].0];
                        if let (Some(u), Some(rig_u)) = (&desc.unit, self.units.get(rig_name)) {
                            if u != rig_u {
                                tracing::warn!(
                                    "opendaq {}: {id} is in {u} but rig channel {rig_name} says {rig_u}; values pass through x sensitivity — fix the rig's unit/sensitivity or the device's scaling",
                                    self.endpoint
                                );
                            }
                        }
                    }
                }
                if let Some((delta, _)) = desc.linear_time() {
                    domains
                        .entry(signo)
                        .or_insert(Domain {
                            index: 0,
                            ticks: 0,
                            delta,
                        })
                        .delta = delta;
                    if let Some(r) = desc.sample_rate() {
                        if (r - fs).abs() > 1e-9 * fs {
                            problem = Some(format!(
                                "{id} is stamped at {r} Hz but rigmon runs at {fs} Hz (the rate it found at start-up); restart rigmon to follow the device"
                            ));
                        }
                    }
                }
            }
            if let Some(p) = problem.take() {
                return Some(p);
            }
            for &(signo, first_index, at, n) in &events {
                // Domains match no channel; one signal may feed several rig channels.
                for k in (0..bound.len()).filter(|&k| bound[k].signo == Some(signo)) {
                    let vals = &values[at..at + n];
                    let desc = bound[k].desc.as_ref();
                    let dom = desc
                        .and_then(|d| d.domain_id.as_ref())
                        .and_then(|id| session.decoder.signo_of(id))
                        .and_then(|s| domains.get(&s).copied())
                        .filter(|d| d.delta > 0);
                    let Some(dom) = dom else {
                        bad_local += 1;
                        misfit.warn(|| format!("opendaq {}: values of {} before its time domain was described; skipped", self.endpoint, ids[k]));
                        continue;
                    };
                    if clock.origin.is_none() {
                        // Signals subscribed together start a little apart: the clock starts
                        // `max_lag` samples before the first stamp seen, so the others fit.
                        clock.origin = Some(dom.ticks - max_lag as i128 * dom.delta as i128);
                        clock.delta = dom.delta;
                    }
                    let origin = clock.origin.unwrap_or(0);
                    if dom.delta != clock.delta {
                        return Some(format!(
                            "{} has a time step of {} ticks, the clock {}; restart rigmon",
                            ids[k], dom.delta, clock.delta
                        ));
                    }
                    let ticks =
                        dom.ticks + (first_index as i128 - dom.index as i128) * dom.delta as i128;
                    let rel = ticks - origin;
                    if rel < 0 {
                        bad_local += 1;
                        misfit.warn(|| format!("opendaq {}: {} sent values stamped before the start of the clock; skipped", self.endpoint, ids[k]));
                        continue;
                    }
                    let idx = ((rel + dom.delta as i128 / 2) / dom.delta as i128) as u64;
                    aligner.push(k, idx, vals.iter().map(|&v| v as f32));
                    last_data = Instant::now();
                }
            }
            // Rows every channel has: rig order, sensitivity, split into accel + tacho.
            let layout = &self.layout;
            let mapped = &self.mapped;
            aligner.take(&mut |first, rows| {
                let n = rows.first().map_or(0, Vec::len);
                let mut device: Vec<Vec<f32>> = vec![Vec::new(); layout.device_channels()];
                for (k, (i, _)) in mapped.iter().enumerate() {
                    device[*i] = rows[k].clone();
                }
                for d in device.iter_mut() {
                    if d.len() != n {
                        d.resize(n, f32::NAN);
                    }
                }
                let (accel, tacho) = layout.split(device);
                asm.push(first, &accel, tacho.as_deref(), &[]);
            });
            let lost = aligner.lost() + aligner.stale();
            SourceStats::add(&stats.samples_lost, lost - *seen_lost);
            *seen_lost = lost;
            let bad = session.decoder.counters().bad() + bad_local;
            if bad > seen_bad {
                let c = session.decoder.counters();
                misfit.warn(|| {
                    format!(
                        "opendaq {}: packets skipped: {} meta information that did not decode, {} data packets for undescribed signals or with a partial value, {} values without a time stamp",
                        self.endpoint, c.bad_meta, c.bad_data, bad_local
                    )
                });
            }
            SourceStats::add(&stats.bad_frames, bad - seen_bad);
            seen_bad = bad;
            for b in asm.take_ready() {
                if !offer_block(tx, b, stats) {
                    return None;
                }
            }
            if let Some(g) = gone {
                return Some(g);
            }
        }
    }
}
