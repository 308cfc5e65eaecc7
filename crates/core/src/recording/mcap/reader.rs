//! Reading a rigmon MCAP file, tolerant of damage: as a stream of [`SampleBlock`]s with
//! bounded memory ([`RecordingReader`]: `replay`, `import`), or whole into a [`Recording`]
//! ([`read_recording`]). A damaged chunk is skipped and reading resumes at the next intact one
//! ([`Scanner`]); what could not be read is reported ([`Losses`]: gaps on the sample clock,
//! damaged stretches, a tail cut off, with samples and seconds). In the stream a gap is a jump
//! of `first_sample` (so the daemon's windower flags `dropout` and counts the samples lost);
//! in a whole recording it is filled with NaN (never with silence) and noted. Damaged length
//! fields give errors or skips, not huge allocations or panics.

use super::assemble::{Assembler, Out};
use super::codec::{decode_block, decode_edges};
use super::layout::*;
use super::scan::{lengths_fit, Item, Scanner};
use crate::recording::losses::{Damage, GapCause, Losses, Truncation};
use crate::recording::{Channel, Provenance, Recording, SampleBlock, Tacho};
use anyhow::{bail, Context, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Cursor, Read, Seek};
use std::path::Path;

/// Lost blocks are NaN-filled in a whole recording, up to this many times the samples a
/// stream really holds ...
const MAX_FILL_RATIO: u64 = 16;
/// ... plus this many samples.
const MAX_FILL_EXTRA: u64 = 1 << 20;

/// A rigmon MCAP file read block by block.
pub struct RecordingReader<R> {
    scan: Scanner<R>,
    info: RecordingInfo,
    /// Schema id -> name; channel id -> (topic index in the assembler, or None, schema id).
    schemas: BTreeMap<u16, String>,
    channels: BTreeMap<u16, (Option<usize>, u16, String)>,
    assembler: Assembler,
    losses: Losses,
    /// The samples each damaged stretch skipped is known to have held: a damaged chunk's
    /// declared span, or the furthest sample read before the stretch (a gap near one of them
    /// is a damaged gap, others were never recorded).
    damage_marks: Vec<DamageMark>,
    /// The walk has ended (footer, end of file, cut).
    finished: bool,
    /// A footer without a summary ends the file (its writer had not finished it).
    unfinished: bool,
    messages_on_unknown_channels: u64,
    /// Samples handed out so far (per channel).
    delivered: u64,
    /// End of the last block handed out (the sample clock).
    clock: u64,
    /// Records read while looking for the metadata, handed on first.
    first_records: std::collections::VecDeque<(u8, Vec<u8>, u64)>,
    /// The furthest sample a damaged chunk's header says it held (what a damaged last chunk
    /// took with it).
    damaged_until: u64,
    /// Where the file is cut: byte offset, what is there, the cut chunk's time span.
    truncated: Option<Cut>,
    /// Rewound for another pass: losses were reported on the first.
    quiet: bool,
}

/// Where a file is cut: byte offset, what is there, the cut chunk's time span (first and last
/// sample) when its header could be read.
type Cut = (u64, String, Option<(u64, u64)>);

impl RecordingReader<File> {
    /// Open a rigmon MCAP file: its magic, then its `rigmon.recording` metadata.
    pub fn open(path: &Path) -> Result<Self> {
        let f = File::open(path).with_context(|| format!("{}: cannot read", path.display()))?;
        RecordingReader::new(f).with_context(|| format!("{}", path.display()))
    }
}

impl<R: Read + Seek> RecordingReader<R> {
    pub fn new(src: R) -> Result<Self> {
        let mut scan = Scanner::new(src)?;
        let definitions = scan.summary_definitions()?;
        let mut metadata: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        let mut damage = Vec::new();
        let mut cut: Option<Item> = None;
        let mut first_records = std::collections::VecDeque::new();
        // The metadata records come before any message (definitions may come first).
        while !metadata.contains_key(RECORDING_METADATA) || !metadata.contains_key(LABELS_METADATA)
        {
            match scan.next_item()? {
                Some(Item::Record { opcode, data, .. })
                    if opcode == mcap::records::op::METADATA =>
                {
                    if lengths_fit(opcode, &data).is_err() {
                        continue;
                    }
                    if let Ok(mcap::records::Record::Metadata(m)) =
                        mcap::parse_record(opcode, &data)
                    {
                        metadata.insert(m.name, m.metadata);
                    }
                }
                Some(Item::Record { opcode, data, at }) => {
                    let message = opcode == mcap::records::op::MESSAGE;
                    first_records.push_back((opcode, data, at));
                    if message || first_records.len() > 4096 {
                        break;
                    }
                }
                Some(Item::Damaged { damage: d, span_ns }) => damage.push((d, span_ns)),
                Some(other) => {
                    cut = Some(other);
                    break;
                }
                None => break,
            }
        }
        let Some(rec) = metadata.get(RECORDING_METADATA) else {
            let why = match (&cut, damage.first()) {
                (Some(Item::Truncated { what, at, .. }), _) => {
                    Some(format!("at byte {at}: {what}"))
                }
                (_, Some((d, _))) => Some(format!("at byte {}: {}", d.at_byte, d.what)),
                _ => None,
            };
            match why {
                Some(e) => bail!(
                    "truncated or damaged before the `{RECORDING_METADATA}` metadata record ({e})"
                ),
                None => bail!("not a rigmon recording: no `{RECORDING_METADATA}` metadata record"),
            }
        };
        let info = recording_info(rec, metadata.get(LABELS_METADATA))?;
        let analog = matches!(info.tacho, TachoInfo::Analog { .. });
        let mut reader = RecordingReader {
            assembler: Assembler::new(info.sample_rate, info.channels.len(), analog),
            scan,
            info,
            schemas: BTreeMap::new(),
            channels: BTreeMap::new(),
            losses: Losses::default(),
            damage_marks: Vec::new(),
            finished: false,
            unfinished: false,
            messages_on_unknown_channels: 0,
            delivered: 0,
            clock: 0,
            first_records,
            damaged_until: 0,
            truncated: None,
            quiet: false,
        };
        for (opcode, data) in definitions {
            reader.define(opcode, &data);
        }
        for (d, span_ns) in damage {
            reader.on_item(Item::Damaged { damage: d, span_ns })?;
        }
        if let Some(item) = cut {
            reader.on_item(item)?;
        }
        Ok(reader)
    }

    /// Everything about the recording but its samples.
    pub fn info(&self) -> &RecordingInfo {
        &self.info
    }

    /// [`info`](Self::info), writable (overrides given on the command line).
    pub fn info_mut(&mut self) -> &mut RecordingInfo {
        &mut self.info
    }

    /// What could not be read so far (complete once [`next_block`](Self::next_block) has
    /// returned `None`).
    pub fn losses(&self) -> &Losses {
        &self.losses
    }

    /// Notes for the provenance: what was lost, and oddities that lost nothing.
    pub fn notes(&self) -> Vec<String> {
        let fs = self.info.sample_rate;
        let mut notes = Vec::new();
        if !self.losses.is_empty() {
            notes.push(format!(
                "MCAP file damaged or cut short: {}",
                self.losses.line(fs)
            ));
        }
        if self.unfinished {
            notes.push(
                "no summary after the last chunk: its writer had not finished the file (still \
                 recording, or stopped before the end); read up to its last complete chunk"
                    .into(),
            );
        }
        if self.assembler.overlapped > 0 {
            notes.push(format!(
                "{} samples overlapping earlier ones dropped",
                self.assembler.overlapped
            ));
        }
        if self.messages_on_unknown_channels > 0 {
            notes.push(format!(
                "{} messages on channels whose definition was lost skipped",
                self.messages_on_unknown_channels
            ));
        }
        notes
    }

    /// The recording's length in seconds as its chunk headers declare it (read without
    /// decompressing), when they are legible.
    pub fn declared_duration_s(&mut self) -> Result<Option<f64>> {
        Ok(self
            .scan
            .time_span()?
            .map(|(_, end)| end.saturating_sub(self.info.start_time_ns) as f64 / 1e9))
    }

    /// Start again from the first block. After a whole pass (a looping replay) the losses
    /// stay those of the first pass and are not reported again; before (a look at the first
    /// block) they are forgotten and found again.
    pub fn rewind(&mut self) -> Result<()> {
        self.scan.rewind();
        let analog = matches!(self.info.tacho, TachoInfo::Analog { .. });
        self.assembler = Assembler::new(self.info.sample_rate, self.info.channels.len(), analog);
        if self.finished {
            self.quiet = true;
        } else {
            self.losses = Losses::default();
            self.truncated = None;
        }
        self.finished = false;
        self.delivered = 0;
        self.clock = 0;
        self.damaged_until = 0;
        self.first_records.clear();
        self.damage_marks.clear();
        Ok(())
    }

    /// Register a Schema or Channel record.
    fn define(&mut self, opcode: u8, data: &[u8]) {
        if lengths_fit(opcode, data).is_err() {
            return;
        }
        match mcap::parse_record(opcode, data) {
            Ok(mcap::records::Record::Schema { header, .. }) => {
                self.schemas.insert(header.id, header.name);
            }
            Ok(mcap::records::Record::Channel(c)) => {
                let index = self.topic_index(&c.topic);
                self.channels.insert(c.id, (index, c.schema_id, c.topic));
            }
            _ => {}
        }
    }

    /// Where a topic's samples go in the assembler.
    fn topic_index(&self, topic: &str) -> Option<usize> {
        if let Some(name) = topic.strip_prefix(ACCEL_TOPIC_PREFIX) {
            return self.info.channels.iter().position(|c| c.name == name);
        }
        (topic == TACHO_ANALOG_TOPIC && matches!(self.info.tacho, TachoInfo::Analog { .. }))
            .then_some(self.info.channels.len())
    }

    /// A message: its samples or edges to the assembler; one that does not decode is damage
    /// (skipped and reported), never the end of the reading.
    fn on_message(&mut self, data: &[u8], at: u64) {
        let rec = match mcap::parse_record(mcap::records::op::MESSAGE, data) {
            Ok(mcap::records::Record::Message { header, data }) => (header, data),
            _ => return,
        };
        let Some((index, schema_id, topic)) = self.channels.get(&rec.0.channel_id) else {
            self.messages_on_unknown_channels += 1;
            return;
        };
        let schema = self
            .schemas
            .get(schema_id)
            .map(String::as_str)
            .unwrap_or("");
        let bad = if schema == SAMPLE_BLOCK_SCHEMA {
            match decode_block(&rec.1) {
                Ok(b) => {
                    if let Some(i) = *index {
                        self.assembler.push(i, b.first_sample, b.samples);
                    }
                    None
                }
                Err(e) => Some(format!("a message on {topic} does not decode: {e}")),
            }
        } else if schema == TACHO_EDGES_SCHEMA {
            match decode_edges(&rec.1) {
                Ok((first, _, t)) => {
                    self.assembler.push_edges(first, &t);
                    None
                }
                Err(e) => Some(format!("a message on {topic} does not decode: {e}")),
            }
        } else {
            None
        };
        if let Some(what) = bad {
            self.damage(
                Damage {
                    at_byte: at,
                    bytes: 0,
                    what,
                },
                None,
            );
        }
    }

    fn damage(&mut self, d: Damage, span_ns: Option<(u64, u64)>) {
        if !self.quiet {
            self.losses.damaged.push(d);
        }
        self.damage_marks.push(match span_ns {
            Some((a, b)) => DamageMark::Span(self.sample_at(a), self.sample_at(b)),
            None => DamageMark::After(self.assembler.frontier().unwrap_or(0)),
        });
    }

    /// Why samples `[first, first + samples)` are missing.
    fn gap_cause(&self, first: u64, samples: u64) -> GapCause {
        let (g0, g1) = (first, first + samples);
        let run = self.assembler.max_run().max(1);
        let near = |m: &DamageMark| match *m {
            // The chunk held messages starting in [a, b], each up to a block long.
            DamageMark::Span(a, b) => a < g1 && b + run >= g0,
            // Reading resumed after the stretch: the gap starts about where it stopped.
            DamageMark::After(f) => g0 <= f + 2 * run && g1 >= f,
        };
        if self.damage_marks.iter().any(near) {
            GapCause::Damaged
        } else {
            GapCause::NotRecorded
        }
    }

    fn on_item(&mut self, item: Item) -> Result<()> {
        use mcap::records::op;
        match item {
            Item::Record { opcode, data, at } => match opcode {
                op::MESSAGE => self.on_message(&data, at),
                op::SCHEMA | op::CHANNEL => self.define(opcode, &data),
                _ => {}
            },
            Item::Damaged { damage, span_ns } => {
                if let Some((_, end_ns)) = span_ns {
                    self.damaged_until = self.damaged_until.max(self.sample_at(end_ns));
                }
                self.damage(damage, span_ns);
            }
            Item::Truncated { at, what, span_ns } => {
                self.finished = true;
                if !self.quiet {
                    self.truncated = Some((at, what, span_ns));
                }
            }
            Item::Footer { summary } => {
                self.finished = true;
                self.unfinished = !summary;
            }
        }
        Ok(())
    }

    /// The next block (channels in [`info`](Self::info) order, the analog tacho, the edges
    /// in its span); `None` at the end. Its `first_sample` jumps where samples are missing.
    pub fn next_block(&mut self) -> Result<Option<SampleBlock>> {
        loop {
            if let Some(out) = self.assembler.pop(self.finished) {
                match out {
                    Out::Block(b) => {
                        self.delivered += b.len() as u64;
                        self.clock = b.first_sample + b.len() as u64;
                        return Ok(Some(b));
                    }
                    Out::Gap { first, samples } => {
                        if !self.quiet {
                            let cause = self.gap_cause(first, samples);
                            self.losses
                                .add_gap(first, samples, self.info.sample_rate, cause);
                        }
                    }
                    Out::Unmatched { samples } => {
                        if !self.quiet {
                            self.losses.unmatched_samples += samples;
                        }
                    }
                }
                continue;
            }
            if self.finished {
                self.close_damaged_end();
                self.close_truncation();
                return Ok(None);
            }
            let item = match self.first_records.pop_front() {
                Some((opcode, data, at)) => Some(Item::Record { opcode, data, at }),
                None => self.scan.next_item()?,
            };
            match item {
                Some(item) => self.on_item(item)?,
                None => self.finished = true,
            }
        }
    }

    /// The sample a message logged at `t_ns` starts at.
    fn sample_at(&self, t_ns: u64) -> u64 {
        let s = t_ns.saturating_sub(self.info.start_time_ns) as f64 / 1e9;
        (s * self.info.sample_rate).round() as u64
    }

    /// Once the walk has ended: samples a damaged chunk held after the last block handed out
    /// (its header's time span says how far it reached; its last block's length is unknown,
    /// so this is a lower bound) are a gap at the end.
    fn close_damaged_end(&mut self) {
        if self.quiet || self.damaged_until <= self.clock {
            return;
        }
        // Samples some channels had past the last whole block lie in that stretch too.
        let unmatched = std::mem::take(&mut self.losses.unmatched_samples);
        let lost = (self.damaged_until - self.clock).max(unmatched);
        self.losses
            .add_gap(self.clock, lost, self.info.sample_rate, GapCause::Damaged);
        self.damaged_until = 0;
    }

    /// Once the walk has ended: the cut tail, with what its chunk header says it held.
    fn close_truncation(&mut self) {
        let Some((at, what, span)) = self.truncated.take() else {
            return;
        };
        let fs = self.info.sample_rate;
        // The last message starts at end_ns; its block runs a little longer, unknown.
        let end_sample = span.map_or(0, |(_, end_ns)| self.sample_at(end_ns));
        // Samples some channels had past the last whole block lie in the cut stretch too.
        let lost = end_sample
            .saturating_sub(self.clock)
            .max(std::mem::take(&mut self.losses.unmatched_samples));
        self.losses.truncated = Some(Truncation {
            at_byte: at,
            file_bytes: self.scan.file_len(),
            readable_samples: self.clock,
            readable_s: self.clock as f64 / fs,
            lost_samples_at_least: lost,
            lost_s_at_least: lost as f64 / fs,
            what,
        });
    }

    /// Edges left after the last block.
    fn take_edges(&mut self) -> Vec<f64> {
        self.assembler.take_edges()
    }
}

/// What a damaged stretch is known to have held, in samples.
#[derive(Debug, Clone, Copy)]
enum DamageMark {
    /// A damaged chunk whose header declares messages starting from `.0` to `.1`.
    Span(u64, u64),
    /// A stretch skipped after the sample `.0` (the furthest read before it).
    After(u64),
}

/// The `rigmon.recording` record (and the labels) as a [`RecordingInfo`].
fn recording_info(
    info: &BTreeMap<String, String>,
    labels: Option<&BTreeMap<String, String>>,
) -> Result<RecordingInfo> {
    let get = |k: &str| {
        info.get(k)
            .with_context(|| format!("`{RECORDING_METADATA}` record lacks `{k}`"))
    };
    let version = get("layout_version")?;
    if version != LAYOUT_VERSION {
        bail!("rigmon MCAP layout version {version} is not supported (this rigmon reads version {LAYOUT_VERSION})");
    }
    let sample_rate: f64 = get("sample_rate_hz")?.parse().context("sample_rate_hz")?;
    if !(sample_rate.is_finite() && sample_rate > 0.0) {
        bail!("`{RECORDING_METADATA}`: sample_rate_hz = {sample_rate} is not a positive number");
    }
    let start_time_ns: u64 = get("start_time_ns")?.parse().context("start_time_ns")?;
    let rpm = info
        .get("rpm")
        .map(|s| s.parse::<f64>())
        .transpose()
        .context("rpm")?;
    let channels: Vec<ChannelInfo> = serde_json::from_str(get("channels")?).context("channels")?;
    let provenance: Provenance = serde_json::from_str(get("provenance")?).context("provenance")?;
    let tacho = match info.get("tacho").map(String::as_str).unwrap_or("none") {
        "analog" => TachoInfo::Analog {
            unit: info.get("tacho_unit").cloned().unwrap_or_default(),
        },
        "edges" => TachoInfo::Edges,
        _ => TachoInfo::None,
    };
    Ok(RecordingInfo {
        sample_rate,
        start_time_ns,
        channels,
        tacho,
        rpm,
        provenance,
        metadata: labels.cloned().unwrap_or_default(),
    })
}

/// Read a rigmon MCAP file whole. A file cut short or damaged yields every intact chunk;
/// samples missing on the sample clock are NaN; both are noted in the provenance.
pub fn read_recording(path: &Path) -> Result<Recording> {
    read_recording_with_losses(path).map(|(rec, _)| rec)
}

/// [`read_recording`], and what could not be read.
pub fn read_recording_with_losses(path: &Path) -> Result<(Recording, Losses)> {
    let reader = RecordingReader::open(path)?;
    collect(reader).with_context(|| format!("{}", path.display()))
}

/// [`read_recording`] from bytes in memory.
pub fn read_recording_bytes(bytes: &[u8]) -> Result<Recording> {
    read_recording_bytes_with_losses(bytes).map(|(rec, _)| rec)
}

/// [`read_recording_with_losses`] from bytes in memory.
pub fn read_recording_bytes_with_losses(bytes: &[u8]) -> Result<(Recording, Losses)> {
    collect(RecordingReader::new(Cursor::new(bytes))?)
}

/// Read every block of a stream into a whole recording (gaps NaN-filled).
fn collect<R: Read + Seek>(mut reader: RecordingReader<R>) -> Result<(Recording, Losses)> {
    let mut blocks = Vec::new();
    while let Some(b) = reader.next_block()? {
        blocks.push(b);
    }
    let info = reader.info().clone();
    let losses = reader.losses().clone();
    let present: u64 = blocks.iter().map(|b| b.len() as u64).sum();
    let total = blocks.last().map_or(0, |b| b.first_sample + b.len() as u64);
    // NaN-filling is for lost blocks; a damaged first_sample must not make a tiny file
    // claim gigabytes (found by fuzzing).
    let fill_limit = present.saturating_mul(MAX_FILL_RATIO) + MAX_FILL_EXTRA;
    if total - present > fill_limit {
        bail!(
            "a block starts at sample {} but only {present} samples are recorded: filling the gap \
             with NaN would exceed {fill_limit} samples; the file is damaged",
            blocks.last().map_or(0, |b| b.first_sample)
        );
    }
    if total == 0 {
        match &losses.truncated {
            Some(t) if t.readable_samples == 0 && !losses.damaged.is_empty() => bail!(
                "cut short or damaged before the first complete chunk of samples ({}: {})",
                losses.damaged[0].at_byte,
                losses.damaged[0].what
            ),
            Some(t) => bail!(
                "cut short before the first complete chunk of samples (at byte {}: {})",
                t.at_byte,
                t.what
            ),
            None => bail!("the recording holds no samples"),
        }
    }
    let analog = matches!(info.tacho, TachoInfo::Analog { .. });
    let n_ch = info.channels.len();
    let mut cols: Vec<Vec<f32>> = (0..n_ch + usize::from(analog))
        .map(|_| Vec::with_capacity(total as usize))
        .collect();
    let mut edges = Vec::new();
    let mut notes = Vec::new();
    for b in blocks {
        let at = cols[0].len() as u64;
        if b.first_sample > at {
            notes.push(format!(
                "{} samples missing before sample {} (t = {:.3} s), filled with NaN",
                b.first_sample - at,
                b.first_sample,
                b.first_sample as f64 / info.sample_rate
            ));
            cols.iter_mut()
                .for_each(|c| c.resize(b.first_sample as usize, f32::NAN));
        }
        for (col, samples) in cols.iter_mut().zip(b.channels) {
            col.extend_from_slice(&samples);
        }
        if let (true, Some(t)) = (analog, b.tacho_analog) {
            cols[n_ch].extend_from_slice(&t);
        }
        edges.extend(b.tacho_edges);
    }
    // Edges stored past the last sample are kept, unless the file was cut inside a record.
    let rest = reader.take_edges();
    if losses
        .truncated
        .as_ref()
        .is_none_or(|t| t.at_byte >= t.file_bytes)
    {
        edges.extend(rest);
    }
    let mut provenance = info.provenance.clone();
    provenance.notes.extend(reader.notes());
    provenance.notes.extend(notes);
    let analog_samples = if analog { cols.pop() } else { None };
    let tacho = match &info.tacho {
        TachoInfo::Analog { unit } => Some(Tacho::Analog {
            samples: analog_samples.unwrap_or_default(),
            unit: unit.clone(),
        }),
        TachoInfo::Edges => {
            edges.sort_by(f64::total_cmp);
            Some(Tacho::Edges { times_s: edges })
        }
        TachoInfo::None => None,
    };
    let channels = info
        .channels
        .iter()
        .zip(cols)
        .map(|(c, samples)| Channel {
            name: c.name.clone(),
            axis: c.axis.clone(),
            unit: c.unit.clone(),
            samples,
        })
        .collect();
    Ok((
        Recording {
            sample_rate: info.sample_rate,
            start_time_ns: info.start_time_ns,
            channels,
            tacho,
            rpm: info.rpm,
            nominal_rpm: None,
            provenance,
            metadata: info.metadata,
        },
        losses,
    ))
}
