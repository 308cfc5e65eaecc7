//! Integration tests of the importers (CWRU/MFPT .mat, WAV, CSV) and the rigmon MCAP layout:
//! round trips through files written here by independent code (hound, hand-built MAT v5 bytes,
//! CSV text), the real CWRU files, error messages for bad input, truncated MCAP files, the
//! Python `mcap` package as an independent reader, and the `rigmon import` command.

use rigmon::config::RigConfig;
use rigmon::importers::{self, ImportOptions};
use rigmon::recording::mcap::{self, RecordingInfo, RecordingWriter, WriterSettings};
use rigmon::recording::{Channel, Provenance, Recording, Tacho};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------- helpers

use crate::common::shared_data as data_dir;

fn cwru(rel: &str) -> PathBuf {
    data_dir().join("cwru").join(rel)
}

fn rig_text(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config")
            .join(name),
    )
    .unwrap()
}

fn rig(name: &str) -> RigConfig {
    RigConfig::parse(&rig_text(name)).unwrap()
}

/// lut-rig with `sensitivity = 2.0` on the vertical channel.
fn lut_rig_scaled() -> RigConfig {
    let t = rig_text("lut-rig.toml").replacen(
        "name = \"vertical\"",
        "name = \"vertical\"\nsensitivity = 2.0",
        1,
    );
    let r = RigConfig::parse(&t).unwrap();
    assert_eq!(r.channels[1].sensitivity, 2.0);
    r
}

fn no_opts() -> ImportOptions {
    ImportOptions::default()
}

/// Deterministic test signal.
fn signal(n: usize, seed: f64) -> Vec<f64> {
    (0..n)
        .map(|i| (i as f64 * 0.37 + seed).sin() * 0.8 + (i as f64 * 0.011 * seed).cos() * 0.15)
        .collect()
}

fn err_of<T: std::fmt::Debug>(r: anyhow::Result<T>) -> String {
    format!("{:#}", r.expect_err("expected an error"))
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error message lacks {p:?}:\n{msg}");
    }
}

/// `rigmon <args> --rig config/lut-rig.toml`.
fn rigmon_cmd(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .arg("--rig")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml"))
        .output()
        .unwrap()
}

// ------------------------------------------- an independent MAT v5 builder

struct Mat {
    be: bool,
}

impl Mat {
    fn u32(&self, v: u32) -> [u8; 4] {
        if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    }

    fn file(&self, elements: &[Vec<u8>]) -> Vec<u8> {
        let mut h = format!(
            "{:<116}",
            "MATLAB 5.0 MAT-file, written by the rigmon integration test"
        )
        .into_bytes();
        h.extend_from_slice(&[0; 8]);
        if self.be {
            h.extend_from_slice(&[0x01, 0x00, b'M', b'I']);
        } else {
            h.extend_from_slice(&[0x00, 0x01, b'I', b'M']);
        }
        for e in elements {
            h.extend_from_slice(e);
        }
        h
    }

    /// Data element: tag, data, zero padding to 8 bytes.
    fn el(&self, ty: u32, data: &[u8]) -> Vec<u8> {
        let mut v = self.u32(ty).to_vec();
        v.extend_from_slice(&self.u32(data.len() as u32));
        v.extend_from_slice(data);
        v.resize(v.len().div_ceil(8) * 8, 0);
        v
    }

    fn head(&self, class: u32, dims: &[u32], name: &str) -> Vec<u8> {
        let mut flags = self.u32(class).to_vec();
        flags.extend_from_slice(&[0; 4]);
        let mut b = self.el(6, &flags);
        let d: Vec<u8> = dims.iter().flat_map(|&x| self.u32(x)).collect();
        b.extend(self.el(5, &d));
        b.extend(self.el(1, name.as_bytes()));
        b
    }

    fn double(&self, name: &str, rows: u32, cols: u32, v: &[f64]) -> Vec<u8> {
        let mut b = self.head(6, &[rows, cols], name);
        let raw: Vec<u8> = v
            .iter()
            .flat_map(|x| {
                if self.be {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        b.extend(self.el(9, &raw));
        self.el(14, &b)
    }

    /// A numeric array of MATLAB class `class` (mxCLASS) whose data is `raw` of data type `ty`.
    fn numeric(&self, name: &str, class: u32, ty: u32, dims: [u32; 2], raw: &[u8]) -> Vec<u8> {
        let mut b = self.head(class, &dims, name);
        b.extend(self.el(ty, raw));
        self.el(14, &b)
    }

    /// An int16-class array.
    fn int16(&self, name: &str, rows: u32, cols: u32, v: &[i16]) -> Vec<u8> {
        let raw: Vec<u8> = v
            .iter()
            .flat_map(|x| {
                if self.be {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        self.numeric(name, 10, 3, [rows, cols], &raw)
    }

    /// A single-class array.
    fn single(&self, name: &str, rows: u32, cols: u32, v: &[f32]) -> Vec<u8> {
        let raw: Vec<u8> = v
            .iter()
            .flat_map(|x| {
                if self.be {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        self.numeric(name, 7, 7, [rows, cols], &raw)
    }

    /// A double stored as int16 data (MATLAB's space-saving trick).
    fn double_as_int16(&self, name: &str, v: &[i16]) -> Vec<u8> {
        let mut b = self.head(6, &[v.len() as u32, 1], name);
        let raw: Vec<u8> = v
            .iter()
            .flat_map(|x| {
                if self.be {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        b.extend(self.el(3, &raw));
        self.el(14, &b)
    }

    fn text(&self, name: &str, s: &str) -> Vec<u8> {
        let mut b = self.head(4, &[1, s.len() as u32], name);
        let raw: Vec<u8> = s
            .encode_utf16()
            .flat_map(|x| {
                if self.be {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        b.extend(self.el(4, &raw));
        self.el(14, &b)
    }

    /// A 1x1 struct; `fields` are full miMATRIX elements with empty names.
    fn structure(&self, name: &str, fields: &[(&str, Vec<u8>)]) -> Vec<u8> {
        let mut b = self.head(2, &[1, 1], name);
        let len = 32u32;
        b.extend(self.el(5, &self.u32(len)));
        let mut names = Vec::new();
        for (n, _) in fields {
            let mut x = n.as_bytes().to_vec();
            x.resize(len as usize, 0);
            names.extend(x);
        }
        b.extend(self.el(1, &names));
        for (_, f) in fields {
            b.extend_from_slice(f);
        }
        self.el(14, &b)
    }

    /// Wrap a full miMATRIX element in miCOMPRESSED (no padding after it, as MATLAB writes).
    fn compressed(&self, matrix: &[u8]) -> Vec<u8> {
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
        z.write_all(matrix).unwrap();
        let z = z.finish().unwrap();
        let mut v = self.u32(15).to_vec();
        v.extend_from_slice(&self.u32(z.len() as u32));
        v.extend(z);
        v
    }
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn as_f32(v: &[f64]) -> Vec<f32> {
    v.iter().map(|&x| x as f32).collect()
}

// ------------------------------------------------------------- MAT files

#[test]
fn cwru_style_mat_round_trips_in_both_byte_orders_plain_and_compressed() {
    let dir = tempfile::tempdir().unwrap();
    let de = signal(3000, 1.0);
    let fe = signal(3000, 2.0);
    for be in [false, true] {
        for z in [false, true] {
            let m = Mat { be };
            let wrap = |e: Vec<u8>| if z { m.compressed(&e) } else { e };
            let bytes = m.file(&[
                wrap(m.double("X105_DE_time", 3000, 1, &de)),
                wrap(m.double("X105_FE_time", 3000, 1, &fe)),
                wrap(m.double("X105RPM", 1, 1, &[1797.0])),
                wrap(m.text("note", "renamed file")),
            ]);
            // The file name says nothing: the record number comes from the variable names.
            let path = write(dir.path(), &format!("renamed_{be}_{z}.mat"), &bytes);
            let rec = importers::load(&path, &rig("cwru-de.toml"), &no_opts()).unwrap();
            assert_eq!(rec.sample_rate, 12_000.0, "CWRU catalogue: 105 is 12 kHz");
            assert_eq!(rec.rpm, Some(1797.0));
            assert_eq!(rec.channels.len(), 2, "no BA variable -> BA left out");
            assert_eq!(rec.channel("DE").unwrap().samples, as_f32(&de));
            assert_eq!(rec.channel("FE").unwrap().samples, as_f32(&fe));
            assert_eq!(rec.channel("DE").unwrap().unit, "g");
            assert_eq!(rec.label(), Some("inner_race"));
            assert_eq!(rec.provenance.format, "cwru-mat");
            assert_eq!(
                rec.metadata.get("rig_id").map(String::as_str),
                Some("cwru-de")
            );
            assert_eq!(
                RigConfig::parse(&rec.metadata["rig_config"]).unwrap(),
                rig("cwru-de.toml"),
                "the rig TOML travels along"
            );
            // And through MCAP.
            let out = dir.path().join(format!("r_{be}_{z}.mcap"));
            mcap::write_recording(&out, &rec).unwrap();
            assert_eq!(mcap::read_recording(&out).unwrap(), rec);
        }
    }
}

#[test]
fn cwru_sample_rate_precedence_and_unknown_records() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mat { be: false };
    let mk = |num: &str| {
        m.file(&[
            m.double(&format!("X{num}_DE_time"), 500, 1, &signal(500, 3.0)),
            m.double(&format!("X{num}RPM"), 1, 1, &[1772.0]),
        ])
    };
    let p97 = write(dir.path(), "a.mat", &mk("097"));
    assert_eq!(
        importers::load(&p97, &rig("cwru-de.toml"), &no_opts())
            .unwrap()
            .sample_rate,
        48_000.0
    );
    // The flag overrides the catalogue, and --rpm the stored speed.
    let r = importers::load(
        &p97,
        &rig("cwru-de.toml"),
        &ImportOptions {
            sample_rate: Some(12_000.0),
            rpm: Some(1750.0),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((r.sample_rate, r.rpm), (12_000.0, Some(1750.0)));
    // A rig rate is only the default: the catalogue's rate wins and the note says so.
    let rig12 = RigConfig::parse(&rig_text("cwru-de.toml").replacen(
        "[[channels]]",
        "[acquisition]\nsample_rate_hz = 12000.0\n\n[[channels]]",
        1,
    ))
    .unwrap();
    let r = importers::load(&p97, &rig12, &no_opts()).unwrap();
    assert_eq!(r.sample_rate, 48_000.0);
    assert!(
        r.provenance
            .notes
            .iter()
            .any(|n| n.contains("CWRU catalogue (record 97)") && n.contains("default")),
        "{:?}",
        r.provenance.notes
    );
    // A rate declared beside the file (a manifest column) that contradicts the catalogue is a
    // mismatch naming both numbers; one that agrees is fine.
    let declared = |fs: f64| ImportOptions {
        declared_sample_rate: Some((fs, "labels.csv line 2, column sample_rate_hz".into())),
        ..Default::default()
    };
    let e = err_of(importers::load(&p97, &rig12, &declared(12_000.0)));
    assert_mentions(
        &e,
        &[
            "a.mat",
            "sample-rate mismatch",
            "48000",
            "12000",
            "CWRU catalogue",
            "labels.csv line 2",
        ],
    );
    assert_eq!(
        importers::load(&p97, &rig12, &declared(48_000.0))
            .unwrap()
            .sample_rate,
        48_000.0
    );
    // A record not in the catalogue, no rig rate: ask for --sample-rate.
    let p999 = write(dir.path(), "b.mat", &mk("999"));
    let e = err_of(importers::load(&p999, &rig("cwru-de.toml"), &no_opts()));
    assert_mentions(&e, &["b.mat", "999", "--sample-rate"]);
    assert_eq!(
        importers::load(&p999, &rig12, &no_opts())
            .unwrap()
            .sample_rate,
        12_000.0
    );
    // ...or a manifest row's rate.
    assert_eq!(
        importers::load(&p999, &rig("cwru-de.toml"), &declared(48_000.0))
            .unwrap()
            .sample_rate,
        48_000.0
    );
    // Integer-typed storage of a double array is decoded.
    let pi = write(
        dir.path(),
        "c.mat",
        &m.file(&[m.double_as_int16("X105_DE_time", &[1, -2, 300, -32768])]),
    );
    let r = importers::load(&pi, &rig("cwru-de.toml"), &no_opts()).unwrap();
    assert_eq!(r.channels[0].samples, vec![1.0, -2.0, 300.0, -32768.0]);
    assert_eq!(r.rpm, None);
}

#[test]
fn mfpt_struct_compressed_big_endian_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let gs = signal(4000, 5.0);
    let m = Mat { be: true };
    let bearing = m.structure(
        "bearing",
        &[
            ("sr", m.double("", 1, 1, &[48828.0])),
            ("gs", m.double("", 4000, 1, &gs)),
            ("load", m.double("", 1, 1, &[270.0])),
            ("rate", m.double("", 1, 1, &[25.0])),
            (
                "extra",
                m.structure("", &[("nested", m.double("", 1, 2, &[1.0, 2.0]))]),
            ),
        ],
    );
    let path = write(
        dir.path(),
        "baseline_1.mat",
        &m.file(&[m.compressed(&bearing)]),
    );
    let rec = importers::load(&path, &rig("cwru-de.toml"), &no_opts()).unwrap();
    assert_eq!(rec.provenance.format, "mfpt-mat");
    assert_eq!(rec.sample_rate, 48828.0);
    assert_eq!(rec.rpm, Some(1500.0));
    assert_eq!(rec.metadata.get("load").map(String::as_str), Some("270"));
    assert_eq!(rec.channels.len(), 1);
    assert_eq!(
        rec.channels[0].name, "DE",
        "the signal goes on the rig's classifier channel"
    );
    assert_eq!(rec.channels[0].samples, as_f32(&gs));
    // The rig says 10 kHz, the file 48828 Hz: the file's own rate wins (the rig's is a default).
    let r = importers::load(&path, &rig("lut-rig.toml"), &no_opts()).unwrap();
    assert_eq!(r.sample_rate, 48828.0);
    assert!(r
        .provenance
        .notes
        .iter()
        .any(|n| n.contains("bearing.sr") && n.contains("10000")));
    // Missing field.
    let nogs = m.structure("bearing", &[("sr", m.double("", 1, 1, &[48828.0]))]);
    let p2 = write(dir.path(), "nogs.mat", &m.file(&[nogs]));
    let e = err_of(importers::load(&p2, &rig("cwru-de.toml"), &no_opts()));
    assert_mentions(&e, &["nogs.mat", "missing variable", "gs"]);
}

/// The shipped MFPT rig file (`config/mfpt.toml`, from the data set's sheet) gives the
/// published fault frequencies at 25 Hz (BPFO 81.125 Hz, BPFI 118.875 Hz), and an MFPT file
/// imports onto its one channel at the file's own rate and speed.
#[test]
fn the_mfpt_rig_file_matches_the_published_fault_frequencies() {
    let rig = rig("mfpt.toml");
    let hz = rig.bearing.fault_orders().at_hz(25.0);
    assert!((hz.bpfo - 81.125).abs() < 0.05, "BPFO {} Hz", hz.bpfo);
    assert!((hz.bpfi - 118.875).abs() < 0.05, "BPFI {} Hz", hz.bpfi);
    let dir = tempfile::tempdir().unwrap();
    let gs = signal(3000, 3.0);
    let m = Mat { be: false };
    let bearing = m.structure(
        "bearing",
        &[
            ("sr", m.double("", 1, 1, &[97656.0])),
            ("gs", m.double("", 3000, 1, &gs)),
            ("load", m.double("", 1, 1, &[270.0])),
            ("rate", m.double("", 1, 1, &[25.0])),
        ],
    );
    let p = write(
        dir.path(),
        "baseline_2.mat",
        &m.file(&[m.compressed(&bearing)]),
    );
    let rec = importers::load(&p, &rig, &no_opts()).unwrap();
    assert_eq!((rec.sample_rate, rec.rpm), (97656.0, Some(1500.0)));
    assert_eq!(rec.channels.len(), 1);
    assert_eq!(rec.channels[0].name, "accel");
    assert_eq!(rec.channels[0].samples, as_f32(&gs));
}

/// The public MFPT set's variable-load files store `bearing.load` as text ('25', '100', '300')
/// next to numeric sr/rate: they import, with the load read from the text. Side data that still
/// cannot be read (load "heavy", rate as a 1x2 vector, rate 0) is a warning kept as text in the
/// provenance; the required fields stay strict.
#[test]
fn mfpt_variable_load_files_with_text_load_import() {
    let dir = tempfile::tempdir().unwrap();
    let gs = signal(2000, 7.0);
    for be in [false, true] {
        let m = Mat { be };
        for (name, load, want) in [
            ("InnerRaceFault_vload_1.mat", "25", "25"),
            ("InnerRaceFault_vload_4.mat", "100", "100"),
            ("OuterRaceFault_vload_7.mat", "300", "300"),
        ] {
            let bearing = m.structure(
                "bearing",
                &[
                    ("sr", m.double("", 1, 1, &[48828.0])),
                    ("gs", m.double("", 2000, 1, &gs)),
                    ("load", m.text("", load)),
                    ("rate", m.double("", 1, 1, &[25.0])),
                ],
            );
            let p = write(dir.path(), name, &m.file(&[m.compressed(&bearing)]));
            let rec = importers::load(&p, &rig("cwru-de.toml"), &no_opts())
                .unwrap_or_else(|e| panic!("{name} (be={be}): {e:#}"));
            assert_eq!(rec.sample_rate, 48828.0);
            assert_eq!(rec.rpm, Some(1500.0));
            assert_eq!(rec.metadata.get("load").map(String::as_str), Some(want));
            assert_eq!(rec.channels[0].samples, as_f32(&gs));
            assert!(
                !rec.provenance
                    .notes
                    .iter()
                    .any(|n| n.starts_with(importers::WARNING)),
                "{:?}",
                rec.provenance.notes
            );
        }
    }
    // Unreadable side data: warnings, the signal is kept.
    let m = Mat { be: false };
    let bearing = m.structure(
        "bearing",
        &[
            ("sr", m.double("", 1, 1, &[97656.0])),
            ("gs", m.double("", 2000, 1, &gs)),
            ("load", m.text("", "heavy")),
            ("rate", m.double("", 1, 2, &[25.0, 26.0])),
        ],
    );
    let p = write(dir.path(), "odd.mat", &m.file(&[bearing]));
    let rec = importers::load(&p, &rig("cwru-de.toml"), &no_opts()).unwrap();
    assert_eq!((rec.sample_rate, rec.rpm, rec.len()), (97656.0, None, 2000));
    assert!(!rec.metadata.contains_key("load"));
    let warnings: Vec<&String> = rec
        .provenance
        .notes
        .iter()
        .filter(|n| n.starts_with(importers::WARNING))
        .collect();
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert_mentions(warnings[0], &["bearing.rate", "1x2 double", "[25 26]"]);
    assert_mentions(warnings[1], &["bearing.load", "1x5 char", "\"heavy\""]);
    let bearing = m.structure(
        "bearing",
        &[
            ("sr", m.double("", 1, 1, &[48828.0])),
            ("gs", m.double("", 2000, 1, &gs)),
            ("rate", m.double("", 1, 1, &[0.0])),
        ],
    );
    let p = write(dir.path(), "stopped.mat", &m.file(&[bearing]));
    let rec = importers::load(&p, &rig("cwru-de.toml"), &no_opts()).unwrap();
    assert_eq!(rec.rpm, None);
    assert!(rec
        .provenance
        .notes
        .iter()
        .any(|n| n.starts_with(importers::WARNING) && n.contains("bearing.rate = 0")));
    // The sample rate stays strict: sr as text is refused, naming the field.
    let bearing = m.structure(
        "bearing",
        &[
            ("sr", m.text("", "48828")),
            ("gs", m.double("", 2000, 1, &gs)),
        ],
    );
    let p = write(dir.path(), "srtext.mat", &m.file(&[bearing]));
    assert_mentions(
        &err_of(importers::load(&p, &rig("cwru-de.toml"), &no_opts())),
        &["srtext.mat", "bearing.sr", "1x5 char", "single number"],
    );
}

/// CWRU `X<nnn>RPM` is side data: stored as text it is read, unreadable it is a warning.
#[test]
fn cwru_rpm_in_any_class_or_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mat { be: false };
    let de = signal(600, 2.0);
    let p = write(
        dir.path(),
        "t.mat",
        &m.file(&[
            m.double("X282_DE_time", 600, 1, &de),
            m.double("X282_FE_time", 600, 1, &de),
            m.text("X282RPM", "1798"),
        ]),
    );
    let r = importers::load(&p, &rig("cwru-fe.toml"), &no_opts()).unwrap();
    assert_eq!((r.sample_rate, r.rpm), (12_000.0, Some(1798.0)));
    assert_eq!(
        r.label(),
        Some("ball"),
        "282: fan-end ball fault, seen from FE"
    );
    let p = write(
        dir.path(),
        "u.mat",
        &m.file(&[
            m.double("X282_DE_time", 600, 1, &de),
            m.double("X282_FE_time", 600, 1, &de),
            m.text("X282RPM", "n/a"),
        ]),
    );
    let r = importers::load(&p, &rig("cwru-fe.toml"), &no_opts()).unwrap();
    assert_eq!(r.rpm, None);
    assert!(r
        .provenance
        .notes
        .iter()
        .any(|n| n.starts_with(importers::WARNING)
            && n.contains("X282RPM")
            && n.contains("\"n/a\"")));
    // Seen from the drive-end rig, the fan-end fault leaves the monitored bearing healthy.
    let r = importers::load(&p, &rig("cwru-de.toml"), &no_opts()).unwrap();
    assert_eq!(r.label(), Some("healthy"));
    assert_eq!(r.metadata["cwru_fault"], "ball");
    assert_eq!(r.metadata["cwru_fault_bearing"], "FE");
}

// ------------------------------------------------------------- WAV and CSV

fn write_wav(path: &Path, spec: hound::WavSpec, frames: &[Vec<f64>]) {
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for f in frames {
        for &x in f {
            match spec.sample_format {
                hound::SampleFormat::Float => w.write_sample(x as f32).unwrap(),
                hound::SampleFormat::Int => {
                    let full = (1i64 << (spec.bits_per_sample - 1)) as f64;
                    w.write_sample((x * full).round().clamp(-full, full - 1.0) as i32)
                        .unwrap()
                }
            }
        }
    }
    w.finalize().unwrap();
}

/// 4 columns for lut-rig: axial, vertical, horizontal in -1..1, tacho pulses 0/0.9.
fn frames(n: usize) -> Vec<Vec<f64>> {
    let (a, v, h) = (signal(n, 1.0), signal(n, 2.0), signal(n, 3.0));
    (0..n)
        .map(|i| {
            vec![
                a[i] * 0.9,
                v[i] * 0.9,
                h[i] * 0.9,
                if i % 100 < 10 { 0.9 } else { 0.0 },
            ]
        })
        .collect()
}

#[test]
fn wav_float32_int16_int24_round_trip_with_channel_map_and_sensitivity() {
    let dir = tempfile::tempdir().unwrap();
    let rig = lut_rig_scaled();
    let fr = frames(2500);
    for (bits, format) in [
        (32, hound::SampleFormat::Float),
        (16, hound::SampleFormat::Int),
        (24, hound::SampleFormat::Int),
    ] {
        let spec = hound::WavSpec {
            channels: 4,
            sample_rate: 10_000,
            bits_per_sample: bits,
            sample_format: format,
        };
        let path = dir.path().join(format!("rig_{bits}.wav"));
        write_wav(&path, spec, &fr);
        let rec = importers::load(&path, &rig, &no_opts()).unwrap();
        assert_eq!(rec.sample_rate, 10_000.0);
        assert_eq!(rec.len(), 2500);
        let names: Vec<&str> = rec.channels.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["axial", "vertical", "horizontal"]);
        let tol = match bits {
            32 => 1e-7,
            16 => 1.0 / 32768.0,
            _ => 1.0 / 8_388_608.0,
        };
        for (k, ch) in rec.channels.iter().enumerate() {
            let scale = if ch.name == "vertical" { 2.0 } else { 1.0 };
            for (i, &x) in ch.samples.iter().enumerate() {
                let want = fr[i][k] * scale;
                assert!(
                    (x as f64 - want).abs() <= tol * scale + 1e-7,
                    "{bits}-bit {} sample {i}: {x} vs {want}",
                    ch.name
                );
            }
        }
        let Some(Tacho::Analog { samples, unit }) = &rec.tacho else {
            panic!("tacho should be analog")
        };
        assert_eq!(unit, "V");
        assert!((samples[5] - 0.9).abs() < 1e-3 && samples[50].abs() < 1e-6);
        let out = dir.path().join(format!("rig_{bits}.mcap"));
        mcap::write_recording(&out, &rec).unwrap();
        assert_eq!(mcap::read_recording(&out).unwrap(), rec);
    }
}

#[test]
fn wav_errors_name_the_problem() {
    let dir = tempfile::tempdir().unwrap();
    let rig = rig("lut-rig.toml");
    let spec = hound::WavSpec {
        channels: 4,
        sample_rate: 8000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let p = dir.path().join("slow.wav");
    write_wav(&p, spec, &frames(100));
    // The header fixes the rate; the rig's 10 kHz is only a default.
    assert_eq!(
        importers::load(&p, &rig, &no_opts()).unwrap().sample_rate,
        8000.0
    );
    // A manifest row that says otherwise is a real conflict: both numbers, both places.
    let e = err_of(importers::load(
        &p,
        &rig,
        &ImportOptions {
            declared_sample_rate: Some((
                10_000.0,
                "labels.csv line 7, column sample_rate_hz".into(),
            )),
            ..Default::default()
        },
    ));
    assert_mentions(
        &e,
        &[
            "slow.wav",
            "sample-rate mismatch",
            "8000",
            "10000",
            "WAV header",
            "labels.csv line 7",
        ],
    );
    assert_eq!(
        importers::load(
            &p,
            &rig,
            &ImportOptions {
                sample_rate: Some(8000.0),
                ..Default::default()
            }
        )
        .unwrap()
        .sample_rate,
        8000.0
    );
    // Side chunks (LIST/INFO before the data) are skipped.
    let bytes = std::fs::read(&p).unwrap();
    let data_at = bytes.windows(4).position(|w| w == b"data").unwrap();
    let mut info = b"INFOICMT".to_vec();
    let text = b"rig 7, bearing 3\0";
    info.extend_from_slice(&(text.len() as u32).to_le_bytes());
    info.extend_from_slice(text);
    if info.len() % 2 == 1 {
        info.push(0);
    }
    let mut list = b"LIST".to_vec();
    list.extend_from_slice(&(info.len() as u32).to_le_bytes());
    list.extend_from_slice(&info);
    let mut with_list = bytes[..data_at].to_vec();
    with_list.extend_from_slice(&list);
    with_list.extend_from_slice(&bytes[data_at..]);
    let riff_len = (with_list.len() - 8) as u32;
    with_list[4..8].copy_from_slice(&riff_len.to_le_bytes());
    let pl = write(dir.path(), "list.wav", &with_list);
    let r = importers::load(&pl, &rig, &no_opts()).unwrap();
    assert_eq!((r.sample_rate, r.len()), (8000.0, 100));
    // Wrong channel count.
    let p3 = dir.path().join("three.wav");
    write_wav(
        &p3,
        hound::WavSpec {
            channels: 3,
            sample_rate: 10_000,
            ..spec
        },
        &frames(10)
            .into_iter()
            .map(|f| f[..3].to_vec())
            .collect::<Vec<_>>(),
    );
    assert_mentions(
        &err_of(importers::load(&p3, &rig, &no_opts())),
        &["three.wav", "3 channel", "4", "axial"],
    );
    // Inf in a float WAV: channel and sample index.
    let mut fr = frames(100);
    fr[42][2] = f64::INFINITY;
    let pi = dir.path().join("inf.wav");
    write_wav(
        &pi,
        hound::WavSpec {
            sample_rate: 10_000,
            ..spec
        },
        &fr,
    );
    assert_mentions(
        &err_of(importers::load(&pi, &rig, &no_opts())),
        &["inf.wav", "\"horizontal\"", "sample 42", "inf"],
    );
    // Truncated: cut the data chunk mid-way.
    let good = dir.path().join("good.wav");
    write_wav(
        &good,
        hound::WavSpec {
            sample_rate: 10_000,
            ..spec
        },
        &frames(1000),
    );
    let bytes = std::fs::read(&good).unwrap();
    let pt = write(dir.path(), "cut.wav", &bytes[..bytes.len() / 2 + 3]);
    assert_mentions(
        &err_of(importers::load(&pt, &rig, &no_opts())),
        &["cut.wav", "truncated"],
    );
}

#[test]
fn csv_round_trips_with_and_without_time_column() {
    let dir = tempfile::tempdir().unwrap();
    let rig = lut_rig_scaled();
    let (v, a) = (signal(800, 4.0), signal(800, 5.0));
    // Columns in another order than the rig's; a time column at 10 kHz; a comment line.
    let mut text = String::from("# exported by a DAQ\ntime,vertical,axial,tacho\n");
    for i in 0..800 {
        text.push_str(&format!(
            "{},{},{},{}\n",
            i as f64 * 1e-4,
            v[i],
            a[i],
            if i % 50 == 0 { 5 } else { 0 }
        ));
    }
    let p = write(dir.path(), "daq.csv", text.as_bytes());
    let rec = importers::load(&p, &rig, &no_opts()).unwrap();
    assert_eq!(rec.sample_rate, 10_000.0);
    assert_eq!(
        rec.channels
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>(),
        ["axial", "vertical"]
    );
    assert_eq!(rec.channel("axial").unwrap().samples, as_f32(&a));
    assert_eq!(
        rec.channel("vertical").unwrap().samples,
        v.iter().map(|&x| (x * 2.0) as f32).collect::<Vec<_>>()
    );
    assert!(
        matches!(&rec.tacho, Some(Tacho::Analog { samples, .. }) if samples[0] == 5.0 && samples[1] == 0.0)
    );
    // A 5 kHz time column on a rig without a rate: the column decides.
    let mut t5 = String::from("t;DE\n");
    for (i, x) in v.iter().enumerate().take(300) {
        t5.push_str(&format!("{};{x}\n", i as f64 / 5000.0));
    }
    let p5 = write(dir.path(), "de.csv", t5.as_bytes());
    let r5 = importers::load(
        &p5,
        &RigConfig::parse(&rig_text("cwru-de.toml")).unwrap(),
        &no_opts(),
    )
    .unwrap();
    assert_eq!((r5.sample_rate, r5.len()), (5000.0, 300));
    // No time column: the rig's rate.
    let p0 = write(
        dir.path(),
        "plain.csv",
        format!("vertical\n{}\n{}\n", v[0], v[1]).as_bytes(),
    );
    assert_eq!(
        importers::load(&p0, &rig, &no_opts()).unwrap().sample_rate,
        10_000.0
    );
    // Through MCAP.
    let out = dir.path().join("daq.mcap");
    mcap::write_recording(&out, &rec).unwrap();
    assert_eq!(mcap::read_recording(&out).unwrap(), rec);
}

#[test]
fn csv_errors_name_line_column_channel_and_sample() {
    let dir = tempfile::tempdir().unwrap();
    let rig = rig("lut-rig.toml");
    let p = write(dir.path(), "nan.csv", b"vertical,axial\n1,2\n3,4\n5,NaN\n");
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["nan.csv", "\"axial\"", "sample 2", "NaN"],
    );
    let p = write(dir.path(), "text.csv", b"vertical\n1\nabc\n");
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["text.csv", "line 3", "\"abc\" is not a number"],
    );
    // A column naming no rig channel is side data: skipped (values unread) with a warning.
    let p = write(dir.path(), "cols.csv", b"vertical,bogus\n1,n/a\n2,\n");
    let r = importers::load(&p, &rig, &no_opts()).unwrap();
    assert_eq!(r.channel("vertical").unwrap().samples, vec![1.0, 2.0]);
    let w: Vec<&String> = r
        .provenance
        .notes
        .iter()
        .filter(|n| n.starts_with(importers::WARNING))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", r.provenance.notes);
    assert_mentions(
        w[0],
        &["line 1", "2 \"bogus\"", "name no rig channel", "vertical"],
    );
    let p = write(dir.path(), "cut.csv", b"vertical,axial\n1,2\n3,4\n5");
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["cut.csv", "line 4", "truncated"],
    );
    let p = write(
        dir.path(),
        "uneven.csv",
        b"time,vertical\n0,1\n0.0001,2\n0.0003,3\n",
    );
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["uneven.csv", "uneven time step"],
    );
    let p = write(
        dir.path(),
        "rate.csv",
        b"time,vertical\n0,1\n0.001,2\n0.002,3\n",
    );
    assert_eq!(
        importers::load(&p, &rig, &no_opts()).unwrap().sample_rate,
        1000.0,
        "the time column fixes the rate; the rig's is a default"
    );
    assert_mentions(
        &err_of(importers::load(
            &p,
            &rig,
            &ImportOptions {
                declared_sample_rate: Some((
                    10_000.0,
                    "labels.csv line 3, column sample_rate_hz".into(),
                )),
                ..Default::default()
            },
        )),
        &[
            "rate.csv",
            "sample-rate mismatch",
            "time column",
            "1000",
            "10000",
            "labels.csv line 3",
        ],
    );
    let p = write(dir.path(), "noclass.csv", b"axial\n1\n2\n");
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["noclass.csv", "missing", "\"vertical\"", "classifier"],
    );
}

/// Quoted fields (a header name holding the delimiter, quoted numbers, a side-data cell with a
/// comma), CRLF line ends and a byte-order mark are read as CSV means them; ragged rows and an
/// unclosed quote are errors naming the file, the line and what to do.
#[test]
fn csv_quoted_fields_crlf_and_bom_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let rig = rig("lut-rig.toml");
    // A quoted side-data header holding a comma, quoted numeric cells, a quoted side-data cell
    // holding a comma, a doubled quote; CRLF line ends; a BOM before the time column's name.
    let text = "\u{feff}time,\"vertical\",\"temperature, degC\",axial\r\n\
                # a comment, with \"quotes\r\n\
                0,\"1.5\",\"41,5\",2\r\n\
                \r\n\
                0.001,\"-2.5e-1\",\"n/a, \"\"off\"\"\",3\r\n\
                0.002, \"4\" ,42,\"5\"\r\n";
    let p = write(dir.path(), "quoted.csv", text.as_bytes());
    let r = importers::load(&p, &rig, &no_opts()).unwrap();
    assert_eq!(
        r.sample_rate, 1000.0,
        "the BOM must not hide the time column"
    );
    assert_eq!(r.channel("vertical").unwrap().samples, [1.5, -0.25, 4.0]);
    assert_eq!(r.channel("axial").unwrap().samples, [2.0, 3.0, 5.0]);
    let w: Vec<&String> = r
        .provenance
        .notes
        .iter()
        .filter(|n| n.starts_with(importers::WARNING))
        .collect();
    assert_eq!(w.len(), 1, "{:?}", r.provenance.notes);
    assert_mentions(w[0], &["line 1", "3 \"temperature, degC\""]);
    // A semicolon file whose quoted header name holds a comma: the delimiter is `;`.
    let p = write(
        dir.path(),
        "semi.csv",
        b"\"speed, rpm\";vertical\n1500;\"0,5\"\n1500;1\n",
    );
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &[
            "semi.csv",
            "line 2",
            "column 2",
            "\"vertical\"",
            "\"0,5\" is not a number",
        ],
    );
    // Ragged rows (a comma outside quotes adds a cell) and the line they are on, CRLF counted.
    let p = write(
        dir.path(),
        "ragged.csv",
        b"vertical,axial\r\n1,2\r\n# note\r\n3,4,5\r\n",
    );
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["ragged.csv", "line 4", "3 values", "2 columns", "quote"],
    );
    // A quote opened and never closed swallows the rest of the file: said so, with its line.
    let p = write(dir.path(), "open.csv", b"vertical,axial\n1,2\n\"3,4\n5,6\n");
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["open.csv", "line 3", "column 1", "not closed"],
    );
    // Only a BOM and comments: empty.
    let p = write(
        dir.path(),
        "bom.csv",
        "\u{feff}# nothing\r\n\r\n".as_bytes(),
    );
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["bom.csv", "empty"],
    );
}

// ------------------------------------------------------------- any MAT layout

/// The HIT-SM rig file with `edit` applied to its text (one acceleration channel, 51.2 kHz).
fn hit_rig_with(edit: impl Fn(String) -> String) -> RigConfig {
    RigConfig::parse(&edit(rig_text("hit-sm-self.toml")))
        .unwrap_or_else(|e| panic!("edited hit-sm-self.toml: {e:#}"))
}

/// The HIT-SM rig file naming `Data` and `SampleFrequency` (and no default rate).
fn data_rig(var: &str, rate_var: &str) -> RigConfig {
    hit_rig_with(|t| {
        t.replacen(
            "sample_rate_hz = 51200.0",
            &format!("mat_rate_variable = {rate_var:?}"),
            1,
        )
        .replacen(
            "unit = \"g\"",
            &format!("unit = \"g\"\nmat_variable = {var:?}"),
            1,
        )
    })
}

#[test]
fn any_single_vector_maps_to_a_one_channel_rig_whatever_its_name() {
    let dir = tempfile::tempdir().unwrap();
    let hit = rig("hit-sm-self.toml");
    let x = signal(2000, 3.0);
    let ints: Vec<i16> = x.iter().map(|&v| (v * 3000.0) as i16).collect();
    let singles: Vec<f32> = x.iter().map(|&v| v as f32).collect();
    for be in [false, true] {
        for z in [false, true] {
            let m = Mat { be };
            let wrap = |e: Vec<u8>| if z { m.compressed(&e) } else { e };
            // (variable, its bytes, the samples expected on the channel)
            let cases: [(&str, Vec<u8>, Vec<f32>); 4] = [
                ("VarName5", m.double("VarName5", 2000, 1, &x), as_f32(&x)),
                (
                    "inside2d_1200_1",
                    m.double("inside2d_1200_1", 1, 2000, &x),
                    as_f32(&x),
                ),
                (
                    "V0",
                    m.int16("V0", 2000, 1, &ints),
                    ints.iter().map(|&v| v as f32).collect(),
                ),
                (
                    "outside8d_600_1",
                    m.single("outside8d_600_1", 1, 2000, &singles),
                    singles.clone(),
                ),
            ];
            for (name, var, want) in cases {
                // Scalars and text beside the vector are not signals.
                let bytes = m.file(&[
                    wrap(m.text("note", "no layout")),
                    wrap(var),
                    wrap(m.double("gain", 1, 1, &[2.0])),
                ]);
                let path = write(dir.path(), &format!("{name}_{be}_{z}.mat"), &bytes);
                let rec = importers::load(&path, &hit, &no_opts())
                    .unwrap_or_else(|e| panic!("{name} be={be} z={z}: {e:#}"));
                assert_eq!(rec.channels.len(), 1);
                let ch = rec.channel("vertical").unwrap();
                assert_eq!(ch.samples, want, "{name} be={be} z={z}");
                assert_eq!((ch.unit.as_str(), ch.axis.as_str()), ("g", "vertical"));
                assert_eq!(rec.sample_rate, 51_200.0);
                assert_eq!(rec.provenance.format, "mat");
                let notes = rec.provenance.notes.join("\n");
                assert_mentions(
                    &notes,
                    &[
                        &format!("variable {name} ("),
                        "-> rig channel \"vertical\" (the file's only numeric vector)",
                        "sample rate 51200 Hz from the rig file",
                        "other variables not read: note (1x9 char), gain (1x1 double)",
                    ],
                );
                assert_eq!(rec.rpm, None);
                assert_eq!(rec.metadata["rig_id"], "hit-sm-self");
            }
        }
    }
    // The channel's sensitivity applies; --rpm and --sample-rate work as for other formats.
    let scaled = hit_rig_with(|t| t.replacen("unit = \"g\"", "unit = \"g\"\nsensitivity = 2.0", 1));
    let m = Mat { be: false };
    let p = write(
        dir.path(),
        "s.mat",
        &m.file(&[m.double("VarName7", 64, 1, &x[..64])]),
    );
    let opts = ImportOptions {
        rpm: Some(900.0),
        sample_rate: Some(25_600.0),
        ..Default::default()
    };
    let rec = importers::load(&p, &scaled, &opts).unwrap();
    let doubled: Vec<f32> = x[..64].iter().map(|&v| (v * 2.0) as f32).collect();
    assert_eq!(rec.channels[0].samples, doubled);
    assert_eq!((rec.rpm, rec.sample_rate), (Some(900.0), 25_600.0));
}

#[test]
fn data_and_sample_frequency_map_through_the_rigs_keys() {
    let dir = tempfile::tempdir().unwrap();
    let data = signal(3000, 5.0);
    let time: Vec<f64> = (0..3000).map(|i| i as f64 / 25_600.0).collect();
    for z in [false, true] {
        let m = Mat { be: z };
        let wrap = |e: Vec<u8>| if z { m.compressed(&e) } else { e };
        // Two vectors: without the keys this file is refused (below); with them, it maps.
        let bytes = m.file(&[
            wrap(m.double("Time", 3000, 1, &time)),
            wrap(m.double("Data", 3000, 1, &data)),
            wrap(m.int16("SampleFrequency", 1, 1, &[25_600])),
        ]);
        let p = write(dir.path(), &format!("daq_{z}.mat"), &bytes);
        let rec = importers::load(&p, &data_rig("Data", "SampleFrequency"), &no_opts())
            .unwrap_or_else(|e| panic!("z={z}: {e:#}"));
        assert_eq!(rec.sample_rate, 25_600.0, "the file's rate variable");
        assert_eq!(rec.channels[0].samples, as_f32(&data));
        let notes = rec.provenance.notes.join("\n");
        assert_mentions(
            &notes,
            &[
                "variable Data (3000x1 double) -> rig channel \"vertical\" (mat_variable)",
                "sample rate 25600 Hz from the variable SampleFrequency",
                "other variables not read: Time (3000x1 double)",
            ],
        );
        let e = err_of(importers::load(&p, &rig("hit-sm-self.toml"), &no_opts()));
        assert_mentions(
            &e,
            &[
                &format!("daq_{z}.mat"),
                "it holds 2 numeric arrays (Time, Data)",
                "Time (3000x1 double), Data (3000x1 double), SampleFrequency (1x1 int16)",
                "[[channels]] name = \"vertical\"",
                "mat_variable = \"Time\"",
                "mat_rate_variable",
                "not a CWRU file",
                "MFPT",
            ],
        );
    }
    // A struct field path for the signal and the rate; the rig file's rate is only a default.
    let m = Mat { be: false };
    let rec_struct = m.structure(
        "rec",
        &[
            ("accel", m.double("", 1, 500, &data[..500])),
            ("fs", m.double("", 1, 1, &[12_800.0])),
        ],
    );
    let p = write(
        dir.path(),
        "nested.mat",
        &m.file(&[m.compressed(&rec_struct)]),
    );
    let r = data_rig("rec.accel", "rec.fs");
    let rec = importers::load(&p, &r, &no_opts()).unwrap();
    assert_eq!((rec.len(), rec.sample_rate), (500, 12_800.0));
    assert_eq!(rec.channels[0].samples, as_f32(&data[..500]));
    // Named keys win over CWRU recognition: this rig reads X105_DE_time as its one channel.
    let p = write(
        dir.path(),
        "cwru_named.mat",
        &m.file(&[
            m.double("X105_DE_time", 400, 1, &data[..400]),
            m.double("X105_FE_time", 400, 1, &time[..400]),
        ]),
    );
    let r = hit_rig_with(|t| {
        t.replacen(
            "unit = \"g\"",
            "unit = \"g\"\nmat_variable = \"X105_FE_time\"",
            1,
        )
    });
    let rec = importers::load(&p, &r, &no_opts()).unwrap();
    assert_eq!(rec.channels[0].samples, as_f32(&time[..400]));
    assert_eq!(
        (rec.provenance.format.as_str(), rec.sample_rate),
        ("mat", 51_200.0)
    );
}

#[test]
fn matrix_columns_and_a_tacho_map_to_a_multi_channel_rig() {
    let dir = tempfile::tempdir().unwrap();
    let n = 1000;
    // 1000x3, column-major: axial, vertical, horizontal.
    let cols: Vec<Vec<f64>> = (0..3).map(|k| signal(n, k as f64 + 1.0)).collect();
    let acc: Vec<f64> = cols.concat();
    let tacho: Vec<f64> = (0..n)
        .map(|i| if i % 100 < 50 { 5.0 } else { 0.0 })
        .collect();
    let text = rig_text("lut-rig.toml");
    let mut t = text.clone();
    for (name, k) in [("axial", 1), ("vertical", 2), ("horizontal", 3)] {
        t = t.replacen(
            &format!("name = \"{name}\""),
            &format!("name = \"{name}\"\nmat_variable = \"Acc\"\nmat_column = {k}"),
            1,
        );
    }
    t = t.replacen(
        "name = \"tacho\"",
        "name = \"tacho\"\nmat_variable = \"Tach\"",
        1,
    );
    let r = RigConfig::parse(&t).unwrap();
    let m = Mat { be: false };
    let p = write(
        dir.path(),
        "three.mat",
        &m.file(&[
            m.double("Acc", n as u32, 3, &acc),
            m.double("Tach", 1, n as u32, &tacho),
        ]),
    );
    let rec = importers::load(&p, &r, &no_opts()).unwrap();
    for (k, name) in ["axial", "vertical", "horizontal"].iter().enumerate() {
        assert_eq!(
            rec.channel(name).unwrap().samples,
            as_f32(&cols[k]),
            "{name}"
        );
    }
    match &rec.tacho {
        Some(Tacho::Analog { samples, unit }) => {
            assert_eq!(samples, &as_f32(&tacho));
            assert_eq!(unit, "V");
        }
        other => panic!("tacho {other:?}"),
    }
    assert_mentions(
        &rec.provenance.notes.join("\n"),
        &["column 2 of variable Acc (1000x3 double) -> rig channel \"vertical\""],
    );
    // A matrix without a column, a column out of range, samples along the rows.
    let one =
        hit_rig_with(|t| t.replacen("unit = \"g\"", "unit = \"g\"\nmat_variable = \"Acc\"", 1));
    let e = err_of(importers::load(&p, &one, &no_opts()));
    assert_mentions(
        &e,
        &[
            "three.mat",
            "rig channel \"vertical\" (mat_variable = \"Acc\")",
            "1000x3 double",
            "set mat_column = 1 to 3",
        ],
    );
    let far = t.replacen("mat_column = 3", "mat_column = 4", 1);
    let e = err_of(importers::load(
        &p,
        &RigConfig::parse(&far).unwrap(),
        &no_opts(),
    ));
    assert_mentions(&e, &["mat_column = 4 but it has 3 columns"]);
    let p = write(
        dir.path(),
        "rows.mat",
        &m.file(&[
            m.double("Acc", 3, n as u32, &acc),
            m.double("Tach", 1, n as u32, &tacho),
        ]),
    );
    let e = err_of(importers::load(&p, &r, &no_opts()));
    assert_mentions(
        &e,
        &[
            "rows.mat",
            "3x1000 double",
            "only 3 samples",
            "transpose (Acc.')",
        ],
    );
}

#[test]
fn unmappable_mat_files_say_what_they_hold_and_which_key_to_set() {
    let dir = tempfile::tempdir().unwrap();
    let hit = rig("hit-sm-self.toml");
    let m = Mat { be: false };
    let x = signal(100, 1.0);
    let load = |name: &str, els: &[Vec<u8>], r: &RigConfig| {
        err_of(importers::load(
            &write(dir.path(), name, &m.file(els)),
            r,
            &no_opts(),
        ))
    };
    // No numeric vector at all.
    let e = load("text.mat", &[m.text("comment", "hello")], &hit);
    assert_mentions(
        &e,
        &[
            "text.mat",
            "no real numeric vector",
            "comment (1x5 char)",
            "mat_variable",
        ],
    );
    // A matrix is not a vector.
    let e = load("mx.mat", &[m.double("M", 50, 2, &x)], &hit);
    assert_mentions(&e, &["M, is a 50x2 double matrix", "mat_column"]);
    // A named variable the file lacks, a rate variable it lacks, a rate that is a vector.
    let e = load(
        "v.mat",
        &[m.double("Data", 100, 1, &x)],
        &data_rig("Dat", "fs"),
    );
    assert_mentions(
        &e,
        &[
            "v.mat",
            "missing variable \"Dat\"",
            "rig channel \"vertical\"",
            "Data (100x1 double)",
            "mat_variable",
        ],
    );
    let e = load(
        "fs.mat",
        &[m.double("Data", 100, 1, &x)],
        &data_rig("Data", "fs"),
    );
    assert_mentions(
        &e,
        &[
            "fs.mat",
            "missing variable \"fs\"",
            "acquisition.mat_rate_variable = \"fs\"",
            "Data (100x1 double)",
        ],
    );
    let e = load(
        "fsv.mat",
        &[
            m.double("Data", 100, 1, &x),
            m.double("fs", 1, 2, &[1.0, 2.0]),
        ],
        &data_rig("Data", "fs"),
    );
    assert_mentions(&e, &["wrong shape", "fs is 1x2 double", "one number"]);
    // No rate anywhere: the scalars are offered as candidates for the key.
    let no_rate = hit_rig_with(|t| t.replacen("sample_rate_hz = 51200.0", "", 1));
    let e = load(
        "norate.mat",
        &[
            m.double("Data", 100, 1, &x),
            m.double("SampleFrequency", 1, 1, &[51_200.0]),
        ],
        &no_rate,
    );
    assert_mentions(
        &e,
        &[
            "norate.mat",
            "sample rate is unknown",
            "SampleFrequency = 51200",
            "mat_rate_variable",
            "--sample-rate",
        ],
    );
    // A text or struct variable named as a channel; a struct path through a non-struct.
    let e = load("txt.mat", &[m.text("Data", "abc")], &data_rig("Data", "fs"));
    assert_mentions(
        &e,
        &[
            "wrong shape",
            "mat_variable = \"Data\"",
            "1x3 char",
            "real numbers",
        ],
    );
    let s = m.structure("Data", &[("gs", m.double("", 100, 1, &x))]);
    let e = load("st.mat", std::slice::from_ref(&s), &data_rig("Data", "fs"));
    assert_mentions(&e, &["1x1 struct", "mat_variable = \"Data.<field>\""]);
    let e = load(
        "nofield.mat",
        &[s, m.double("fs", 1, 1, &[1e3])],
        &data_rig("Data.sig", "fs"),
    );
    assert_mentions(
        &e,
        &["missing field", "Data has no field \"sig\"", "[\"gs\"]"],
    );
    let e = load(
        "notstruct.mat",
        &[m.double("Data", 100, 1, &x)],
        &data_rig("Data.sig", "fs"),
    );
    assert_mentions(
        &e,
        &["Data is 100x1 double, not a 1x1 struct with a field \"sig\""],
    );
}

/// The mapping is settled on the variable directory before samples are decoded: a file whose
/// signal is damaged deep inside its compressed data is refused for its layout, naming its
/// variables, without decoding; naming the damaged variable then reaches the damage.
#[test]
fn mat_layout_is_refused_before_any_sample_is_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mat { be: false };
    let mut x: u64 = 3;
    let noise: Vec<f64> = (0..50_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % 4096) as f64
        })
        .collect();
    let big = m.compressed(&m.double("Big", 50_000, 1, &noise));
    let mut bytes = m.file(&[big, m.double("Other", 10, 1, &noise[..10])]);
    let end = bytes.len() - m.double("Other", 10, 1, &noise[..10]).len();
    for b in &mut bytes[end - 64..end - 48] {
        *b ^= 0xa5;
    }
    let p = write(dir.path(), "damaged.mat", &bytes);
    let e = err_of(importers::load(&p, &rig("hit-sm-self.toml"), &no_opts()));
    assert_mentions(
        &e,
        &[
            "damaged.mat",
            "Big (50000x1 double), Other (10x1 double)",
            "mat_variable",
        ],
    );
    let e = err_of(importers::load(&p, &data_rig("Big", "Other"), &no_opts()));
    assert_mentions(
        &e,
        &["damaged.mat", "Other is 10x1 double; expected one number"],
    );
    let r = hit_rig_with(|t| t.replacen("unit = \"g\"", "unit = \"g\"\nmat_variable = \"Big\"", 1));
    let e = err_of(importers::load(&p, &r, &no_opts()));
    assert_mentions(
        &e,
        &["damaged.mat", "MAT file at byte 128", "does not decompress"],
    );
}

/// Damaged files of any layout give errors, never a panic, through the directory, the
/// mapping and the selective decoding.
#[test]
fn damaged_any_layout_mat_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let rigs = [
        rig("hit-sm-self.toml"),
        data_rig("rec.accel", "SampleFrequency"),
    ];
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    for z in [false, true] {
        let m = Mat { be: z };
        let wrap = |e: Vec<u8>| if z { m.compressed(&e) } else { e };
        let st = m.structure("rec", &[("accel", m.double("", 1, 64, &signal(64, 2.0)))]);
        let base = m.file(&[
            wrap(m.double("VarName5", 64, 1, &signal(64, 1.0))),
            wrap(m.int16("SampleFrequency", 1, 1, &[12_000])),
            wrap(st),
        ]);
        let path = dir.path().join(format!("m{z}.mat"));
        let (mut accepted, mut refused) = (0, 0);
        for _ in 0..400 {
            let mut b = base.clone();
            for _ in 0..1 + next() % 3 {
                let k = 120 + (next() as usize) % (b.len() - 120);
                b[k] = next() as u8;
            }
            let cut = if next() % 4 == 0 {
                120 + (next() as usize) % (b.len() - 120)
            } else {
                b.len()
            };
            std::fs::write(&path, &b[..cut]).unwrap();
            for r in &rigs {
                match importers::load(&path, r, &no_opts()) {
                    Ok(_) => accepted += 1,
                    Err(_) => refused += 1,
                }
            }
        }
        assert!(
            accepted > 0 && refused > 0,
            "accepted {accepted}, refused {refused}"
        );
    }
}

#[test]
fn rig_mat_keys_are_checked_when_the_rig_file_is_read() {
    let text = rig_text("lut-rig.toml");
    let bad = |edit: &str, on: &str| {
        let t = text.replacen(
            &format!("name = \"{on}\""),
            &format!("name = \"{on}\"\n{edit}"),
            1,
        );
        format!("{:#}", RigConfig::parse(&t).expect_err(edit))
    };
    assert_mentions(
        &bad("mat_column = 2", "axial"),
        &["\"axial\"", "mat_column needs mat_variable"],
    );
    assert_mentions(
        &bad("mat_variable = \"A\"\nmat_column = 0", "vertical"),
        &["mat_column = 0", "count from 1"],
    );
    assert_mentions(
        &bad("mat_variable = \"a..b\"", "vertical"),
        &["\"a..b\"", "struct field path"],
    );
    assert_mentions(
        &bad("mat_variable = \"my data\"", "vertical"),
        &["\"my data\"", "no spaces"],
    );
    assert_mentions(
        &bad("mat_variable = \"A\"", "axial"),
        &["\"vertical\" feeds the classifier", "names no mat_variable"],
    );
    let t = text
        .replacen(
            "name = \"vertical\"",
            "name = \"vertical\"\nmat_variable = \"A\"",
            1,
        )
        .replacen(
            "name = \"axial\"",
            "name = \"axial\"\nmat_variable = \"A\"\nmat_column = 1",
            1,
        );
    assert_mentions(
        &format!("{:#}", RigConfig::parse(&t).unwrap_err()),
        &["\"axial\" and \"vertical\" both read mat_variable = \"A\" (column 1)"],
    );
    let t = text.replacen(
        "[acquisition]",
        "[acquisition]\nmat_rate_variable = \"\"",
        1,
    );
    assert_mentions(
        &format!("{:#}", RigConfig::parse(&t).unwrap_err()),
        &["acquisition.mat_rate_variable = \"\""],
    );
    // The keys survive the TOML round trip that stamps every imported recording.
    let r = data_rig("rec.accel", "rec.fs");
    assert_eq!(RigConfig::parse(&toml::to_string(&r).unwrap()).unwrap(), r);
    // And rigs without them serialise as before (no new keys appear).
    assert!(!toml::to_string(&rig("cwru-de.toml"))
        .unwrap()
        .contains("mat_"));
}

/// Every file of ../shared/data/hit-sm-self imports as it is, through a manifest with the
/// nominal speeds in an `rpm` column (carried as a hint, not used as the speed), and through
/// `rigmon import` and `rigmon inspect`. The variable names were listed with SciPy's
/// `whosmat`, independently of rigmon.
#[test]
fn every_hit_sm_file_imports_as_it_is() {
    let data = data_dir().join("hit-sm-self");
    assert!(
        data.is_dir(),
        "{} missing: ../shared/data must hold hit-sm-self (see its README)",
        data.display()
    );
    let var = |cond: &str, rpm: &str| -> String {
        match (cond, rpm) {
            ("Normal", "600") => "VarName6".into(),
            ("Normal", "900") => "VarName7".into(),
            ("Normal", "1200") => "V0".into(),
            _ => {
                let side = if cond.starts_with("IR") {
                    "inside"
                } else {
                    "outside"
                };
                format!("{side}{}d_{rpm}_1", &cond[2..])
            }
        }
    };
    let mut found: Vec<String> = std::fs::read_dir(&data)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".mat"))
        .collect();
    found.sort();
    let mut expected = Vec::new();
    for cond in ["IR2", "IR5", "IR8", "Normal", "OR2", "OR5", "OR8"] {
        for rpm in ["1200", "600", "900"] {
            expected.push(format!("{cond}_{rpm}.mat"));
        }
    }
    assert_eq!(found, expected, "the 21 files of the README");
    let tmp = tempfile::tempdir().unwrap();
    let mut csv = String::from("path,label,rpm\n");
    for f in &found {
        let label = match &f[..2] {
            "IR" => "inner_race",
            "OR" => "outer_race",
            _ => "healthy",
        };
        let rpm = f.trim_end_matches(".mat").split('_').nth(1).unwrap();
        csv.push_str(&format!("{},{label},{rpm}\n", data.join(f).display()));
    }
    let labels = write(tmp.path(), "labels.csv", csv.as_bytes());
    let hit = rig("hit-sm-self.toml");
    let entries = rigmon::manifest::read_manifest(&labels).unwrap();
    assert_eq!(entries.len(), 21);
    for (k, e) in entries.iter().enumerate() {
        let stem = e
            .path_text
            .rsplit('/')
            .next()
            .unwrap()
            .trim_end_matches(".mat");
        let (cond, rpm) = stem.split_once('_').unwrap();
        let rec = importers::load(&e.path, &hit, &e.import_options())
            .unwrap_or_else(|err| panic!("{stem}: {err:#}"));
        assert_eq!((rec.len(), rec.sample_rate), (262_144, 51_200.0), "{stem}");
        assert_eq!(rec.duration_s(), 5.12);
        assert_eq!(rec.channels.len(), 1);
        assert_eq!(rec.rpm, None, "{stem}: the nominal speed is not the speed");
        let hint = rec.nominal_rpm.as_ref().expect("the rpm column's hint");
        assert_eq!(hint.rpm, rpm.parse::<f64>().unwrap());
        assert_eq!(
            hint.declared_at,
            format!("labels.csv line {}, column rpm", k + 2)
        );
        assert_mentions(
            &rec.provenance.notes.join("\n"),
            &[
                &format!(
                    "variable {} (262144x1 double) -> rig channel \"vertical\"",
                    var(cond, rpm)
                ),
                &format!("nominal speed {rpm} rpm from labels.csv line {}", k + 2),
            ],
        );
        let s = &rec.channels[0].samples;
        let rms = (s.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / s.len() as f64).sqrt();
        assert!(
            rms > 1e-4 && rms < 1.0,
            "{stem}: rms {rms} (README: levels differ by ~300x)"
        );
    }
    // The command line reads them as they are too.
    let bin = env!("CARGO_BIN_EXE_rigmon");
    let rig_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/hit-sm-self.toml");
    for f in &found {
        let out = tmp.path().join("x.mcap");
        let o = std::process::Command::new(bin)
            .args(["import", "--rig"])
            .arg(&rig_path)
            .arg(data.join(f))
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "import {f}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_mentions(
            &text,
            &["1 channel(s) (vertical), 262144 samples @ 51200 Hz, 5.120 s"],
        );
        let o = std::process::Command::new(bin)
            .args(["inspect", "--rig"])
            .arg(&rig_path)
            .arg(data.join(f))
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "inspect {f}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert_mentions(
            &String::from_utf8_lossy(&o.stdout),
            &["(source: estimate)", "BPFO 3.5848"],
        );
    }
}

// ------------------------------------------------------------- bad input in general

#[test]
fn empty_files_and_wrong_shapes_and_missing_variables_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let cw = rig("cwru-de.toml");
    for name in ["e.mat", "e.wav", "e.csv", "e.mcap"] {
        let p = write(dir.path(), name, b"");
        assert_mentions(
            &err_of(importers::load(&p, &cw, &no_opts())),
            &[name, "empty"],
        );
    }
    let p = write(dir.path(), "hdr.csv", b"DE\n");
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &["hdr.csv", "no samples"],
    );
    let m = Mat { be: false };
    // Wrong shape: a matrix where a vector belongs.
    let p = write(
        dir.path(),
        "matrix.mat",
        &m.file(&[m.double("X105_DE_time", 2, 500, &signal(1000, 1.0))]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &[
            "matrix.mat",
            "wrong shape",
            "X105_DE_time",
            "2x500",
            "column vector",
        ],
    );
    // A row vector is accepted.
    let p = write(
        dir.path(),
        "row.mat",
        &m.file(&[m.double("X105_DE_time", 1, 64, &signal(64, 1.0))]),
    );
    assert_eq!(importers::load(&p, &cw, &no_opts()).unwrap().len(), 64);
    // The classifier's channel is missing.
    let p = write(
        dir.path(),
        "nofe.mat",
        &m.file(&[m.double("X105_FE_time", 64, 1, &signal(64, 1.0))]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &[
            "nofe.mat",
            "missing variable X105_DE_time",
            "X105_FE_time (64x1 double)",
        ],
    );
    // Neither CWRU nor MFPT.
    let p = write(
        dir.path(),
        "other.mat",
        &m.file(&[m.double("data", 3, 1, &[1.0, 2.0, 3.0])]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &[
            "other.mat",
            "the rig has 3 acceleration channels (DE, FE, BA) and none names its variable",
            "X<nnn>_DE_time",
            "bearing",
            "data (3x1 double)",
            "under [[channels]] name = \"DE\" set mat_variable = \"data\"",
        ],
    );
    // NaN in a MAT signal.
    let mut s = signal(64, 1.0);
    s[17] = f64::NAN;
    let p = write(
        dir.path(),
        "nan.mat",
        &m.file(&[m.double("X105_DE_time", 64, 1, &s)]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &["nan.mat", "\"DE\"", "sample 17", "NaN"],
    );
    // Lengths differ between channels.
    let p = write(
        dir.path(),
        "len.mat",
        &m.file(&[
            m.double("X105_DE_time", 64, 1, &signal(64, 1.0)),
            m.double("X105_FE_time", 60, 1, &signal(60, 1.0)),
        ]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &["len.mat", "60", "64"],
    );
    // A rig whose channels are not CWRU sensors.
    let p = write(
        dir.path(),
        "ok.mat",
        &m.file(&[m.double("X105_DE_time", 64, 1, &signal(64, 1.0))]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &rig("lut-rig.toml"), &no_opts())),
        &["ok.mat", "DE, FE or BA", "cwru-de.toml"],
    );
    // Unknown format.
    let p = write(dir.path(), "x.bin", b"\x01\x02\x03");
    assert_mentions(
        &err_of(importers::load(&p, &cw, &no_opts())),
        &["x.bin", "unknown recording format"],
    );
}

#[test]
fn truncated_real_cwru_file_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(cwru("12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat")).unwrap();
    for cut in [100, 128 + 4, 1_000_000, bytes.len() - 1] {
        let p = write(dir.path(), "105_cut.mat", &bytes[..cut]);
        let e = err_of(importers::load(&p, &rig("cwru-de.toml"), &no_opts()));
        assert_mentions(&e, &["105_cut.mat", "truncated"]);
    }
}

// ------------------------------------------------------------- real CWRU files

#[test]
fn real_cwru_files_load_with_catalogue_rates_and_stored_rpm() {
    let rig = rig("cwru-de.toml");
    let cases: [(&str, f64, Option<usize>, &str); 7] = [
        ("97_Normal_0.mat", 48_000.0, Some(243_938), "healthy"),
        (
            "12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat",
            12_000.0,
            Some(121_265),
            "inner_race",
        ),
        (
            "12k_Drive_End_Bearing_Fault_Data/IR/021/209_0.mat",
            12_000.0,
            None,
            "inner_race",
        ),
        (
            "12k_Drive_End_Bearing_Fault_Data/OR/007/@6/130@6_0.mat",
            12_000.0,
            None,
            "outer_race",
        ),
        (
            "12k_Drive_End_Bearing_Fault_Data/OR/021/@6/234_0.mat",
            12_000.0,
            None,
            "outer_race",
        ),
        (
            "12k_Drive_End_Bearing_Fault_Data/B/007/118_0.mat",
            12_000.0,
            None,
            "ball",
        ),
        (
            "12k_Drive_End_Bearing_Fault_Data/B/021/222_0.mat",
            12_000.0,
            None,
            "ball",
        ),
    ];
    for (rel, fs, n, label) in cases {
        let rec = importers::load(&cwru(rel), &rig, &no_opts())
            .unwrap_or_else(|e| panic!("{rel}: {e:#}"));
        assert_eq!(rec.sample_rate, fs, "{rel}");
        if let Some(n) = n {
            assert_eq!(rec.len(), n, "{rel}");
        }
        let dur = rec.duration_s();
        assert!((4.9..10.5).contains(&dur), "{rel}: {dur} s");
        let rpm = rec.rpm.unwrap();
        assert!((1795.5..1797.5).contains(&rpm), "{rel}: rpm {rpm}");
        assert_eq!(rec.label(), Some(label), "{rel}");
        assert_eq!(rec.channel("DE").unwrap().unit, "g");
        // Acceleration in g of a running motor: RMS well above zero, peak below 50 g.
        let de = &rec.channel("DE").unwrap().samples;
        let rms = (de.iter().map(|&x| (x as f64).powi(2)).sum::<f64>() / de.len() as f64).sqrt();
        assert!(
            rms > 0.01 && de.iter().all(|x| x.abs() < 50.0),
            "{rel}: rms {rms}"
        );
    }
    let r97 = importers::load(&cwru("97_Normal_0.mat"), &rig, &no_opts()).unwrap();
    assert_eq!(
        r97.channels
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>(),
        ["DE", "FE"],
        "97 has no BA sensor"
    );
    assert_eq!(r97.rpm, Some(1796.0));
    let r105 = importers::load(
        &cwru("12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat"),
        &rig,
        &no_opts(),
    )
    .unwrap();
    assert_eq!(r105.rpm, Some(1797.0));
    assert_eq!(r105.channels.len(), 3);
}

// ------------------------------------------------------------- MCAP layout

fn synthetic(n: usize, tacho: Option<Tacho>) -> Recording {
    Recording {
        sample_rate: 10_000.0,
        start_time_ns: 1_700_000_000_123_456_789,
        channels: ["axial", "vertical", "horizontal"]
            .iter()
            .enumerate()
            .map(|(k, name)| Channel {
                name: name.to_string(),
                axis: name.to_string(),
                unit: "m/s^2".into(),
                samples: as_f32(&signal(n, k as f64 + 0.5)),
            })
            .collect(),
        tacho,
        rpm: Some(600.5),
        nominal_rpm: None,
        provenance: Provenance {
            source_path: "sim".into(),
            format: "simulated".into(),
            notes: vec!["seed 7".into()],
        },
        metadata: BTreeMap::from([
            ("label".to_string(), "outer_race".to_string()),
            ("seed".to_string(), "7".to_string()),
        ]),
    }
}

fn edges(n: usize, fs: f64) -> Vec<f64> {
    (0..)
        .map(|k| 0.0123 + k as f64 * 0.1001)
        .take_while(|&t| t < n as f64 / fs)
        .collect()
}

#[test]
fn mcap_write_read_is_exact_for_analog_and_edge_tachos() {
    let dir = tempfile::tempdir().unwrap();
    let n = 12_345;
    let analog: Vec<f32> = (0..n)
        .map(|i| if i % 1000 < 100 { 5.0 } else { 0.0 })
        .collect();
    for rec in [
        synthetic(
            n,
            Some(Tacho::Analog {
                samples: analog,
                unit: "V".into(),
            }),
        ),
        synthetic(
            n,
            Some(Tacho::Edges {
                times_s: edges(n, 10_000.0),
            }),
        ),
        synthetic(n, None),
    ] {
        let p = dir.path().join("x.mcap");
        mcap::write_recording(&p, &rec).unwrap();
        let back = mcap::read_recording(&p).unwrap();
        assert_eq!(back, rec);
        // importers::load keeps an MCAP's own provenance and metadata.
        assert_eq!(
            importers::load(&p, &rig("lut-rig.toml"), &no_opts()).unwrap(),
            rec
        );
    }
    let e = err_of(mcap::read_recording(&write(
        dir.path(),
        "not.mcap",
        b"\x89MCAP0\r\nrubbish",
    )));
    assert_mentions(&e, &["not.mcap"]);
}

/// Stream blocks like the daemon does, never finish (as if killed), and cut the file at many
/// places: every cut yields exactly the samples of its complete chunks.
#[test]
fn mcap_streaming_writer_survives_kill_and_truncation() {
    let dir = tempfile::tempdir().unwrap();
    let n_blocks = 60;
    let bl = 250;
    let full = synthetic(n_blocks * bl, None);
    let all_edges = edges(n_blocks * bl, 10_000.0);
    let mut info = RecordingInfo::of(&full);
    info.tacho = mcap::TachoInfo::Edges;
    let p = dir.path().join("stream.mcap");
    let settings = WriterSettings {
        chunk_size: 8 * 1024,
        zstd_level: 1,
    };
    let mut w = RecordingWriter::create_with(&p, &info, &settings).unwrap();
    for b in 0..n_blocks {
        let (s, e) = (b * bl, (b + 1) * bl);
        let chans: Vec<&[f32]> = full.channels.iter().map(|c| &c.samples[s..e]).collect();
        let ed: Vec<f64> = all_edges
            .iter()
            .copied()
            .filter(|&t| t >= s as f64 / 1e4 && t < e as f64 / 1e4)
            .collect();
        w.write_block(s as u64, &chans, None, &ed).unwrap();
        if b == 40 {
            w.flush().unwrap();
        }
    }
    // Killed: no finish, no summary, no footer. Everything flushed at block 40 survives.
    std::mem::forget(w);
    let killed = mcap::read_recording(&p).unwrap();
    assert!(
        killed.len() >= 41 * bl && killed.len() <= full.len(),
        "{}",
        killed.len()
    );
    assert_eq!(killed.len() % bl, 0);
    for (a, b) in killed.channels.iter().zip(&full.channels) {
        assert_eq!(a.samples[..], b.samples[..killed.len()]);
    }
    let Some(Tacho::Edges { times_s }) = &killed.tacho else {
        panic!()
    };
    let want: Vec<f64> = all_edges
        .iter()
        .copied()
        .filter(|&t| t < killed.len() as f64 / 1e4)
        .collect();
    assert_eq!(times_s, &want);
    assert_eq!(killed.metadata, full.metadata);

    // A finished file cut at many places.
    let p2 = dir.path().join("whole.mcap");
    let mut w = RecordingWriter::create_with(&p2, &info, &settings).unwrap();
    for b in 0..n_blocks {
        let chans: Vec<&[f32]> = full
            .channels
            .iter()
            .map(|c| &c.samples[b * bl..(b + 1) * bl])
            .collect();
        w.write_block((b * bl) as u64, &chans, None, &[]).unwrap();
    }
    w.finish().unwrap();
    let bytes = std::fs::read(&p2).unwrap();
    let mut last = 0;
    let mut errors = 0;
    for k in 1..40 {
        let cut = bytes.len() * k / 40;
        match mcap::read_recording_bytes(&bytes[..cut]) {
            Ok(r) => {
                assert!(r.len() >= last, "more bytes never give fewer samples");
                last = r.len();
                for (a, b) in r.channels.iter().zip(&full.channels) {
                    assert_eq!(a.samples[..], b.samples[..r.len()], "cut at {cut}");
                }
                assert!(
                    r.provenance
                        .notes
                        .iter()
                        .any(|n| n.contains("cut short") || n.contains("no footer")),
                    "{:?}",
                    r.provenance.notes
                );
            }
            Err(e) => {
                errors += 1;
                let m = format!("{e:#}");
                assert!(
                    m.contains("cut short") || m.contains("truncated"),
                    "cut at {cut}: {m}"
                );
            }
        }
    }
    assert!(
        errors < 10 && last > full.len() / 2,
        "errors {errors}, last {last}"
    );
}

/// Issue 25, finding 6: blocks the writer never wrote (a recorder that fell behind) were
/// zero-filled (silence) and read as complete. Now they are NaN in a whole recording, noted,
/// and reported as a gap (`not_recorded`) with samples and seconds.
#[test]
fn mcap_gaps_are_never_silence_and_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    let full = synthetic(1000, None);
    let p = dir.path().join("gap.mcap");
    let mut w = RecordingWriter::create(&p, &RecordingInfo::of(&full)).unwrap();
    for b in [0usize, 1, 3] {
        let chans: Vec<&[f32]> = full
            .channels
            .iter()
            .map(|c| &c.samples[b * 250..(b + 1) * 250])
            .collect();
        w.write_block((b * 250) as u64, &chans, None, &[]).unwrap();
    }
    w.finish().unwrap();
    let (r, losses) = mcap::read_recording_with_losses(&p).unwrap();
    assert_eq!(r.len(), 1000);
    assert!(
        r.channels[0].samples[500..750].iter().all(|x| x.is_nan()),
        "a gap is not silence"
    );
    assert_eq!(
        r.channels[0].samples[750..],
        full.channels[0].samples[750..]
    );
    assert!(
        r.provenance
            .notes
            .iter()
            .any(|n| n.contains("250 samples missing before sample 750")),
        "{:?}",
        r.provenance.notes
    );
    assert_eq!(losses.gaps.len(), 1, "{losses:?}");
    let g = &losses.gaps[0];
    assert_eq!((g.first_sample, g.samples), (500, 250));
    assert_eq!(g.cause, rigmon::recording::losses::GapCause::NotRecorded);
    assert!((g.seconds - 0.025).abs() < 1e-12 && (g.at_s - 0.05).abs() < 1e-12);
    assert!(losses.damaged.is_empty() && losses.truncated.is_none());
    // `import` reports the span as incomplete (it said nothing before).
    let out = dir.path().join("gap-out.mcap");
    let o = rigmon_cmd(&[
        "import",
        p.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["losses"]["samples_lost"], 250, "{v}");
    assert_eq!(v["losses"]["gaps"][0]["cause"], "not_recorded", "{v}");
    assert_mentions(
        &String::from_utf8_lossy(&o.stderr),
        &["warning:", "gap.mcap", "0.025 s"],
    );
    // The gap is still a gap in the copy.
    let (_, again) = mcap::read_recording_with_losses(&out).unwrap();
    assert_eq!(again.gap_samples(), 250);
}

// ------------------------------------------------------------- independent reader (Python)

fn python_read(path: &Path, full: bool) -> serde_json::Value {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/read_mcap.py");
    let mut cmd = std::process::Command::new("python3");
    cmd.arg(script).arg(path);
    if full {
        cmd.arg("--full");
    }
    let out = cmd
        .output()
        .expect("python3 must be installed (tests/python/requirements.txt)");
    assert!(
        out.status.success(),
        "read_mcap.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn python_mcap_package_reads_the_layout() {
    let dir = tempfile::tempdir().unwrap();
    let n = 7_001;
    let mut rec = synthetic(
        n,
        Some(Tacho::Analog {
            samples: (0..n).map(|i| (i % 97) as f32 * 0.05).collect(),
            unit: "V".into(),
        }),
    );
    rec.metadata
        .insert("rig_config".into(), rig_text("lut-rig.toml"));
    let p = dir.path().join("py.mcap");
    mcap::write_recording(&p, &rec).unwrap();
    let v = python_read(&p, true);
    assert_eq!(v["profile"], "rigmon");
    assert_eq!(v["schemas"]["rigmon.SampleBlock"], "rigmon-le");
    let meta = &v["metadata"];
    assert_eq!(meta["rigmon.metadata"]["label"], "outer_race");
    assert_eq!(
        meta["rigmon.metadata"]["rig_config"],
        rig_text("lut-rig.toml")
    );
    assert_eq!(meta["rigmon.recording"]["sample_rate_hz"], "10000");
    assert_eq!(meta["rigmon.recording"]["rpm"], "600.5");
    assert_eq!(meta["rigmon.recording"]["tacho"], "analog");
    let prov: serde_json::Value =
        serde_json::from_str(meta["rigmon.recording"]["provenance"].as_str().unwrap()).unwrap();
    assert_eq!(prov["format"], "simulated");
    for c in &rec.channels {
        let ch = &v["channels"][format!("/accel/{}", c.name)];
        assert_eq!(ch["n"], n);
        assert_eq!(ch["unit"], "m/s^2");
        let got: Vec<f32> = ch["samples_bits"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| f32::from_bits(x.as_u64().unwrap() as u32))
            .collect();
        assert_eq!(got, c.samples, "{}", c.name);
    }
    let Some(Tacho::Analog { samples, .. }) = &rec.tacho else {
        unreachable!()
    };
    let t = &v["channels"]["/tacho/analog"];
    assert_eq!(t["unit"], "V");
    let got: Vec<f32> = t["samples_bits"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| f32::from_bits(x.as_u64().unwrap() as u32))
        .collect();
    assert_eq!(&got, samples);

    // Edge times.
    let rec = synthetic(
        5000,
        Some(Tacho::Edges {
            times_s: edges(5000, 10_000.0),
        }),
    );
    mcap::write_recording(&p, &rec).unwrap();
    let v = python_read(&p, false);
    let got: Vec<f64> = v["edges_bits"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| f64::from_bits(x.as_u64().unwrap()))
        .collect();
    assert_eq!(got, edges(5000, 10_000.0));
    assert_eq!(v["schemas"]["rigmon.TachoEdges"], "rigmon-le");

    // A real CWRU file imported: counts and sums agree.
    let r97 = importers::load(&cwru("97_Normal_0.mat"), &rig("cwru-de.toml"), &no_opts()).unwrap();
    mcap::write_recording(&p, &r97).unwrap();
    let v = python_read(&p, false);
    for c in &r97.channels {
        let ch = &v["channels"][format!("/accel/{}", c.name)];
        assert_eq!(ch["n"], 243_938);
        assert_eq!(ch["sample_rate_hz"], 48_000.0);
        let sum: f64 = c.samples.iter().map(|&x| x as f64).sum();
        let sum_sq: f64 = c.samples.iter().map(|&x| (x as f64).powi(2)).sum();
        assert!(
            (ch["sum"].as_f64().unwrap() - sum).abs() <= 1e-9 * sum_sq.max(1.0),
            "{}",
            c.name
        );
        assert!(
            (ch["sum_sq"].as_f64().unwrap() - sum_sq).abs() <= 1e-9 * sum_sq,
            "{}",
            c.name
        );
    }
}

// ------------------------------------------------------------- the command

#[test]
fn rigmon_import_writes_mcap_and_prints_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("105.mcap");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(["import"])
        .arg(cwru("12k_Drive_End_Bearing_Fault_Data/IR/007/105_0.mat"))
        .arg("--rig")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cwru-de.toml"))
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = String::from_utf8(o.stdout).unwrap();
    assert_eq!(line.lines().count(), 1, "{line}");
    assert_mentions(
        &line,
        &[
            "3 channel(s) (DE, FE, BA)",
            "121265 samples @ 12000 Hz",
            "10.105 s",
            "rpm 1797",
            "label inner_race",
        ],
    );
    let rec = mcap::read_recording(&out).unwrap();
    assert_eq!(
        (rec.len(), rec.sample_rate, rec.rpm),
        (121_265, 12_000.0, Some(1797.0))
    );
    // A failing import exits non-zero and says why.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
        .args(["import", "/nonexistent/file.mat", "--rig"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/cwru-de.toml"))
        .arg("-o")
        .arg(dir.path().join("x.mcap"))
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert_mentions(
        &String::from_utf8_lossy(&o.stderr),
        &["/nonexistent/file.mat"],
    );
}

// ------------------------------------- damaged, cut and huge recordings (issue 25)

fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("replay")
        .join(name)
}

/// (offset, record length) of every top-level Chunk record of an MCAP file.
fn chunks_of(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut at = 8;
    let mut out = Vec::new();
    while at + 9 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if at + 9 + len > bytes.len() {
            break;
        }
        if bytes[at] == 0x06 {
            out.push((at, len));
        }
        at += 9 + len;
    }
    out
}

/// The shipped 8 s replay with one byte flipped in the middle of its second (of three)
/// chunks: the file, and the original recording.
fn replay_with_a_flipped_byte(dir: &Path) -> (PathBuf, Recording) {
    let src = shipped("lut-outer_race-588rpm.mcap");
    let mut bytes = std::fs::read(&src).unwrap();
    let chunks = chunks_of(&bytes);
    assert_eq!(chunks.len(), 3, "the shipped replay has three chunks");
    let (at, len) = chunks[1];
    bytes[at + 9 + 60 + len / 2] ^= 0xFF;
    let p = dir.join("flipped.mcap");
    std::fs::write(&p, bytes).unwrap();
    (p, mcap::read_recording(&src).unwrap())
}

/// Issue 25, finding 4: one flipped byte in the middle chunk made every reader stop there
/// (3.2 of 8.0 s, rc 0, nothing printed). The damaged chunk is skipped, the last one read,
/// and the loss reported with samples and seconds.
#[test]
fn a_damaged_chunk_is_skipped_and_reading_resumes_at_the_next_intact_one() {
    let dir = tempfile::tempdir().unwrap();
    let (p, orig) = replay_with_a_flipped_byte(dir.path());
    let (rec, losses) = mcap::read_recording_with_losses(&p).unwrap();
    assert_eq!(rec.len(), orig.len(), "the chunk after the damage is read");
    assert_eq!(losses.damaged.len(), 1, "{losses:?}");
    assert_eq!(losses.gaps.len(), 1, "{losses:?}");
    let g = &losses.gaps[0];
    assert_eq!(g.cause, rigmon::recording::losses::GapCause::Damaged);
    // The chunk held 3.2-6.4 s; the block at 6.4 s lost one channel with it.
    assert_eq!((g.first_sample, g.samples), (32_000, 33_000));
    assert!((g.seconds - 3.3).abs() < 1e-9);
    for (a, b) in rec.channels.iter().zip(&orig.channels) {
        assert_eq!(a.samples[..32_000], b.samples[..32_000]);
        assert!(a.samples[32_000..65_000].iter().all(|x| x.is_nan()));
        assert_eq!(a.samples[65_000..], b.samples[65_000..], "{}", a.name);
    }
    // `features`, `inspect`, ... (importers::load) see the same.
    assert_eq!(
        importers::load(&p, &rig("lut-rig.toml"), &no_opts())
            .unwrap()
            .len(),
        orig.len()
    );
    // `import`: a warning on stderr, the loss in the summary line and the JSON.
    let out = dir.path().join("out.mcap");
    let o = rigmon_cmd(&["import", p.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_mentions(
        &String::from_utf8_lossy(&o.stderr),
        &[
            "warning:",
            "flipped.mcap",
            "damaged",
            "3.300 s (33000 samples)",
        ],
    );
    assert_mentions(
        &String::from_utf8_lossy(&o.stdout),
        &[
            "80000 samples",
            "8.000 s",
            "3.300 s (33000 samples) lost in the input",
        ],
    );
    let o = rigmon_cmd(&[
        "import",
        p.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["losses"]["samples_lost"], 33_000, "{v}");
    assert_eq!(
        v["losses"]["damaged"][0]["at_byte"],
        chunks_of(&std::fs::read(&p).unwrap())[1].0
    );
    assert_eq!(v["samples_present"], 47_000, "{v}");
}

/// Issue 25, finding 5: a recording cut at 50 % read 3.2 of 8.0 s without a word. Now the
/// cut is reported with where it is and the seconds its cut chunk is known to have held.
#[test]
fn a_cut_recording_says_where_and_how_much_was_lost() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(shipped("lut-outer_race-588rpm.mcap")).unwrap();
    let p = dir.path().join("cut.mcap");
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let (rec, losses) = mcap::read_recording_with_losses(&p).unwrap();
    assert_eq!(rec.len(), 32_000);
    let t = losses.truncated.as_ref().expect("reported as cut");
    assert_eq!(
        (t.at_byte, t.file_bytes),
        (chunks_of(&bytes)[1].0 as u64, bytes.len() as u64 / 2)
    );
    // The cut chunk's header says it held messages up to 6.4 s: at least 3.2 s are gone.
    assert_eq!(t.lost_samples_at_least, 32_000);
    assert_eq!(losses.samples_lost(), 32_000);
    assert!(rec.provenance.notes.iter().any(|n| n.contains("cut short")));
    let out = dir.path().join("out.mcap");
    let o = rigmon_cmd(&[
        "import",
        p.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_mentions(
        &String::from_utf8_lossy(&o.stderr),
        &[
            "warning:",
            "cut.mcap",
            "cut short at byte",
            "readable up to 3.200 s",
            "at least 3.200 s",
        ],
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["seconds"], 3.2);
    assert_eq!(v["losses"]["truncated"]["lost_s_at_least"], 3.2, "{v}");
}

/// Issue 25, finding 12: a CSV written with decimal commas got "\"1,5\" is not a number" and
/// no hint. The error now says it looks like decimal commas and what to do.
#[test]
fn a_decimal_comma_csv_gets_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    let r = rig("lut-rig.toml");
    let semicolons = write(
        dir.path(),
        "de.csv",
        b"time;axial;vertical;horizontal;tacho\n0,0;1,5;-0,25;0,125;0\n0,0001;1,5;0,5;1;0\n",
    );
    let e = err_of(importers::load(&semicolons, &r, &no_opts()));
    assert_mentions(
        &e,
        &[
            "de.csv",
            "line 2",
            "column 1",
            "\"0,0\"",
            "decimal comma",
            "1.5, not 1,5",
        ],
    );
    let commas = write(dir.path(), "de2.csv", b"time,axial\n0,0,1,5\n0,1,2,5\n");
    let e = err_of(importers::load(&commas, &r, &no_opts()));
    assert_mentions(
        &e,
        &[
            "de2.csv",
            "line 2",
            "4 values",
            "2 columns",
            "decimal commas",
        ],
    );
    // A plain wrong cell gets no such hint.
    let wrong = write(dir.path(), "w.csv", b"axial\n1.0\nabc\n");
    let e = err_of(importers::load(&wrong, &r, &no_opts()));
    assert!(!e.contains("decimal"), "{e}");
}

/// `rigmon <args>` under GNU time: exit code, stdout, stderr (without time's line) and the
/// peak resident memory, kB. (wait4(2) from this process would count this process's own
/// memory: Linux carries the peak across the spawn's exec.)
fn run_measured(args: &[&str]) -> (i32, String, String, i64) {
    let o = std::process::Command::new("/usr/bin/time")
        .args(["-f", "PEAK_RSS_KB %M", env!("CARGO_BIN_EXE_rigmon")])
        .args(args)
        .output()
        .expect("GNU time (/usr/bin/time, Debian package `time`) measures peak memory");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let (rss_line, rest): (Vec<&str>, Vec<&str>) =
        err.lines().partition(|l| l.starts_with("PEAK_RSS_KB "));
    let rss = rss_line
        .last()
        .and_then(|l| l["PEAK_RSS_KB ".len()..].trim().parse().ok())
        .unwrap_or_else(|| panic!("no peak memory from /usr/bin/time: {err}"));
    let code = o.status.code().unwrap_or(-1);
    // GNU time exits with the command's status.
    (
        code,
        String::from_utf8_lossy(&o.stdout).into_owned(),
        rest.join("\n"),
        rss,
    )
}

/// A 16-bit WAV for lut-rig (3 accelerations + tacho) of `bytes` data bytes, written raw.
fn lut_wav(path: &Path, bytes: usize) {
    let frames = bytes / 8;
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let data = (frames * 8) as u32;
    f.write_all(b"RIFF").unwrap();
    f.write_all(&(36 + data).to_le_bytes()).unwrap();
    f.write_all(b"WAVEfmt ").unwrap();
    for v in [
        16u32.to_le_bytes().to_vec(),
        1u16.to_le_bytes().to_vec(),
        4u16.to_le_bytes().to_vec(),
        10_000u32.to_le_bytes().to_vec(),
        80_000u32.to_le_bytes().to_vec(),
        8u16.to_le_bytes().to_vec(),
        16u16.to_le_bytes().to_vec(),
    ] {
        f.write_all(&v).unwrap();
    }
    f.write_all(b"data").unwrap();
    f.write_all(&data.to_le_bytes()).unwrap();
    let mut frame = [0u8; 8];
    for i in 0..frames {
        for c in 0..3 {
            let x = ((i * (7 + c) % 4001) as i32 - 2000) as i16;
            frame[2 * c..2 * c + 2].copy_from_slice(&x.to_le_bytes());
        }
        // 588 rpm: one 5 V-ish pulse per 1020 samples (the rig's tacho has sensitivity 1).
        let t: i16 = if i % 1020 < 100 { 32_000 } else { 0 };
        frame[6..8].copy_from_slice(&t.to_le_bytes());
        f.write_all(&frame).unwrap();
    }
}

/// Writes the big WAV that docs/reliability.md measures `import` and `replay` on (by hand:
/// `RIGMON_BIG_WAV=/tmp/big.wav cargo test --all-features --test fast write_a_big_wav --
/// --ignored`; `RIGMON_BIG_MIB` sets its data size, 2048 MiB unless given).
#[test]
#[ignore = "writes a 2 GiB file named by RIGMON_BIG_WAV; run by hand"]
fn write_a_big_wav() {
    let path = std::env::var("RIGMON_BIG_WAV").expect("RIGMON_BIG_WAV: where to write the WAV");
    let mib: usize = std::env::var("RIGMON_BIG_MIB").map_or(2048, |v| v.parse().unwrap());
    lut_wav(Path::new(&path), mib << 20);
}

/// Issue 25, finding 3: memory grew with the file (a 2 GiB WAV peaked at 2.1 GB; a file named
/// `.mcap`/`.mat` was read whole before its magic was checked; a `.csv` of NULs peaked at
/// 2.2 GB). `import` and `replay` now stream a 48 MiB WAV with the memory they use for a
/// 1 MiB one, and a file that is not what its name says is refused at once.
#[test]
fn huge_files_stream_with_flat_memory_and_other_files_are_refused_at_once() {
    let dir = match Path::new("/dev/shm").is_dir() {
        true => tempfile::tempdir_in("/dev/shm").unwrap(),
        false => tempfile::tempdir().unwrap(),
    };
    let d = dir.path();
    let (small, big) = (d.join("small.wav"), d.join("big.wav"));
    lut_wav(&small, 1 << 20);
    lut_wav(&big, 48 << 20);
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml");
    let model = Path::new(env!("CARGO_MANIFEST_DIR")).join("models/lut-rig.onnx");
    let (rig, model) = (rig.to_str().unwrap(), model.to_str().unwrap());
    let out = d.join("out.mcap");
    let out = out.to_str().unwrap();
    let import = |f: &Path| run_measured(&["import", f.to_str().unwrap(), "--rig", rig, "-o", out]);
    let replay = |f: &Path| {
        run_measured(&[
            "replay",
            f.to_str().unwrap(),
            "--rig",
            rig,
            "--model",
            model,
            "--quiet",
            "--speed",
            "max",
            "--summary-json",
        ])
    };
    let (rc, _, e, import_small) = import(&small);
    assert_eq!(rc, 0, "{e}");
    let (rc, o, e, import_big) = import(&big);
    assert_eq!(rc, 0, "{e}");
    assert_mentions(&o, &["6291456 samples @ 10000 Hz", "629.146 s"]);
    let (rc, _, e, replay_small) = replay(&small);
    assert_eq!(rc, 0, "{e}");
    let (rc, _, e, replay_big) = replay(&big);
    assert_eq!(rc, 0, "{e}");
    let summary: serde_json::Value =
        serde_json::from_str(e.lines().last().unwrap()).unwrap_or_else(|_| panic!("{e}"));
    assert_eq!(summary["samples_in"], 6_291_456, "{summary}");
    // 48 MiB of 16-bit samples are 96 MiB as f32: holding them whole would add that.
    println!(
        "FIGURE peak RSS, 1 MiB vs 48 MiB WAV: import {import_small} vs {import_big} kB, replay {replay_small} vs {replay_big} kB"
    );
    assert!(
        import_big < import_small + 16 * 1024,
        "import: {import_small} kB vs {import_big} kB"
    );
    assert!(
        replay_big < replay_small + 16 * 1024,
        "replay: {replay_small} kB vs {replay_big} kB"
    );

    // 48 MiB that are not what their names say: refused before being read.
    let junk: Vec<u8> = (0..48u32 << 20)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    let cases: [(&str, Vec<u8>, &[&str]); 4] = [
        ("junk.mcap", junk.clone(), &["not an MCAP file", "48 MiB"]),
        ("junk.mat", junk.clone(), &["not a MAT v5 file", "48 MiB"]),
        ("junk.wav", junk, &["not a WAV file", "48 MiB"]),
        (
            "nul.csv",
            vec![0u8; 48 << 20],
            &["not a text file", "NUL", "line 1", "48 MiB"],
        ),
    ];
    for (name, bytes, want) in cases {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        let t0 = std::time::Instant::now();
        let (rc, _, e, rss) = import(&p);
        let took = t0.elapsed();
        assert_ne!(rc, 0, "{name}");
        assert_mentions(&e, &[name]);
        assert_mentions(&e, want);
        println!(
            "FIGURE {name} (48 MiB): refused in {:.0} ms, peak RSS {rss} kB",
            took.as_secs_f64() * 1e3
        );
        assert!(
            rss < import_small + 8 * 1024,
            "{name}: {rss} kB: read whole before refusing"
        );
        std::fs::remove_file(&p).unwrap();
    }
}

/// Issue 25, finding 12: after kill -9 the trailing placeholder chunk made the Python `mcap`
/// package's usual reader (`make_reader(f).iter_messages()`) return nothing. rigmon's writer
/// now keeps the file a complete MCAP after every chunk: the usual reader reads a file whose
/// writer was killed, up to its last chunk.
#[test]
fn a_killed_writer_leaves_a_file_the_usual_python_reader_reads() {
    let dir = tempfile::tempdir().unwrap();
    let full = synthetic(20 * 500, None);
    let p = dir.path().join("killed.mcap");
    let settings = WriterSettings {
        chunk_size: 16 * 1024,
        zstd_level: 1,
    };
    let mut w = RecordingWriter::create_with(&p, &RecordingInfo::of(&full), &settings).unwrap();
    for b in 0..20 {
        let chans: Vec<&[f32]> = full
            .channels
            .iter()
            .map(|c| &c.samples[b * 500..(b + 1) * 500])
            .collect();
        w.write_block((b * 500) as u64, &chans, None, &[]).unwrap();
        if b == 12 {
            w.flush().unwrap();
        }
    }
    // Killed: no finish, nothing after the last closed chunk reaches the file.
    std::mem::forget(w);
    let rec = mcap::read_recording(&p).unwrap();
    assert!(rec.len() >= 13 * 500, "{}", rec.len());
    let v = python_usual(&p);
    assert_eq!(v["error"], serde_json::Value::Null, "{v}");
    assert_eq!(v["summary"], false, "{v}");
    // Every block rigmon reads whole (a chunk may end inside a block: one channel more).
    let fewest = v["messages"]
        .as_object()
        .unwrap()
        .values()
        .map(|n| n.as_u64().unwrap())
        .min()
        .unwrap();
    assert_eq!(fewest, rec.len() as u64 / 500, "{v}");
}

fn python_usual(path: &Path) -> serde_json::Value {
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/python/read_usual_mcap.py"
    );
    let out = std::process::Command::new("python3")
        .arg(script)
        .arg(path)
        .output()
        .expect("python3 must be installed (tests/python/requirements.txt)");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Issue 25, finding 12: files cut by a writer that left a placeholder chunk (earlier rigmon
/// versions, any writer killed mid-chunk) or damaged: `rigmon repair` rewrites them as
/// finished files that the usual Python reader reads, every intact message included.
#[test]
fn repair_makes_cut_and_damaged_files_readable_by_the_usual_readers() {
    let dir = tempfile::tempdir().unwrap();
    let finished = std::fs::read(shipped("lut-healthy-588rpm.mcap")).unwrap();
    let chunks = chunks_of(&finished);
    // What a writer killed in the middle of its third chunk leaves: two chunks (and their
    // indexes), then a chunk header with placeholder lengths and part of its data.
    let mut cut = finished[..chunks[2].0].to_vec();
    cut.push(0x06);
    cut.extend_from_slice(&u64::MAX.to_le_bytes());
    cut.extend_from_slice(&[0u8; 16]);
    cut.extend_from_slice(&u64::MAX.to_le_bytes());
    cut.extend_from_slice(&u32::MAX.to_le_bytes());
    cut.extend_from_slice(&4u32.to_le_bytes());
    cut.extend_from_slice(b"zstd");
    cut.extend_from_slice(&u64::MAX.to_le_bytes());
    cut.extend_from_slice(&finished[chunks[2].0 + 58..chunks[2].0 + 5000]);
    let (flipped, _) = replay_with_a_flipped_byte(dir.path());
    let cut_path = dir.path().join("cut.mcap");
    std::fs::write(&cut_path, &cut).unwrap();
    // /accel/axial messages in the first two chunks; in the first and the last.
    for (input, intact_blocks) in [(cut_path, 65u64), (flipped, 48)] {
        let before = python_usual(&input);
        let repaired = dir.path().join("repaired.mcap");
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
            .args([
                "repair",
                input.to_str().unwrap(),
                "-o",
                repaired.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let report = String::from_utf8_lossy(&o.stdout);
        let after = python_usual(&repaired);
        println!(
            "FIGURE {}: usual reader before repair {before}; after {after}; {report}",
            input.display()
        );
        assert_eq!(after["error"], serde_json::Value::Null, "{after}");
        assert_eq!(after["summary"], true, "{after}");
        assert_eq!(after["messages"]["/accel/axial"], intact_blocks, "{after}");
        // rigmon reads the same samples from the input and the repair.
        let (a, b) = (
            mcap::read_recording(&input).unwrap(),
            mcap::read_recording(&repaired).unwrap(),
        );
        assert_eq!(a.len(), b.len());
        assert_eq!(
            a.channels[0]
                .samples
                .iter()
                .filter(|x| x.is_finite())
                .count(),
            b.channels[0]
                .samples
                .iter()
                .filter(|x| x.is_finite())
                .count()
        );
        assert!(
            report.contains("damaged") || report.contains("cut at byte"),
            "{report}"
        );
    }
    // The old writer's cut file itself is what the usual reader could not read.
    assert_ne!(
        python_usual(&dir.path().join("cut.mcap"))["error"],
        serde_json::Value::Null
    );
}

// ------------------------------------------------ hostile files (issue 38)

/// A one-channel rig ("vertical", 12 kHz, fixed 1800 rpm), with `extra` under [acquisition].
fn mono_rig(extra: &str) -> RigConfig {
    RigConfig::parse(&format!(
        "[machine]\nid = \"one\"\n[bearing]\nballs = 9\nball_diameter_mm = 7.94\npitch_diameter_mm = 39.04\n\
         [acquisition]\nsample_rate_hz = 12000.0\n{extra}[[channels]]\nname = \"vertical\"\nkind = \"acceleration\"\n\
         axis = \"vertical\"\nunit = \"g\"\n[speed]\nsource = \"fixed\"\nrpm = 1800.0\n[features]\nclassifier_axis = \"vertical\"\n"
    ))
    .unwrap()
}

/// A RIFF/WAVE file from raw chunks (each padded to even length unless `pad` is false), with
/// the RIFF size given or computed.
fn riff(chunks: &[(&[u8; 4], Vec<u8>, Option<u32>)], riff_size: Option<u32>, pad: bool) -> Vec<u8> {
    let mut body = b"WAVE".to_vec();
    for (id, data, size) in chunks {
        body.extend_from_slice(*id);
        body.extend_from_slice(&size.unwrap_or(data.len() as u32).to_le_bytes());
        body.extend_from_slice(data);
        if pad && data.len() % 2 == 1 {
            body.push(0);
        }
    }
    let mut out = b"RIFF".to_vec();
    out.extend_from_slice(&riff_size.unwrap_or(body.len() as u32).to_le_bytes());
    out.extend(body);
    out
}

/// A fmt chunk: PCM (`ext` None) or WAVE_FORMAT_EXTENSIBLE with (valid bits, channel mask,
/// sub-format code).
fn fmt_chunk(channels: u16, container: u16, bits: u16, ext: Option<(u16, u32, u8)>) -> Vec<u8> {
    let align = channels * container;
    let tag: u16 = if ext.is_some() { 0xFFFE } else { 1 };
    let mut f = Vec::new();
    for v in [tag, channels] {
        f.extend_from_slice(&v.to_le_bytes());
    }
    f.extend_from_slice(&12000u32.to_le_bytes());
    f.extend_from_slice(&(12000 * align as u32).to_le_bytes());
    f.extend_from_slice(&align.to_le_bytes());
    f.extend_from_slice(&bits.to_le_bytes());
    if let Some((valid, mask, code)) = ext {
        f.extend_from_slice(&22u16.to_le_bytes());
        f.extend_from_slice(&valid.to_le_bytes());
        f.extend_from_slice(&mask.to_le_bytes());
        f.extend_from_slice(&[
            code, 0, 0, 0, 0, 0, 0x10, 0, 0x80, 0, 0, 0xAA, 0, 0x38, 0x9B, 0x71,
        ]);
    }
    f
}

/// `n` samples of a test signal in -0.9 .. 0.9.
fn mono_signal(n: usize) -> Vec<f64> {
    signal(n, 1.5).iter().map(|x| x * 0.9).collect()
}

fn pcm16(x: &[f64]) -> Vec<u8> {
    x.iter()
        .flat_map(|v| ((v * 32767.0).round() as i16).to_le_bytes())
        .collect()
}

#[test]
fn wav_extensible_24_in_32_reads_like_its_16_bit_copy_and_unknown_formats_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rig = mono_rig("");
    let x = mono_signal(3000);
    let p16 = write(
        dir.path(),
        "a16.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 2, 16, None), None),
                (b"data", pcm16(&x), None),
            ],
            None,
            true,
        ),
    );
    // 24 valid bits left-justified in 32-bit containers, as scipy and MATLAB write them.
    let d24: Vec<u8> = x
        .iter()
        .flat_map(|v| (((v * 8_388_607.0).round() as i32) << 8).to_le_bytes())
        .collect();
    let p24 = write(
        dir.path(),
        "a24in32.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 4, 32, Some((24, 4, 1))), None),
                (b"data", d24, None),
            ],
            None,
            true,
        ),
    );
    // Extensible float and 24-in-24 as well.
    let df: Vec<u8> = x.iter().flat_map(|v| (*v as f32).to_le_bytes()).collect();
    let pf = write(
        dir.path(),
        "af.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 4, 32, Some((32, 4, 3))), None),
                (b"data", df, None),
            ],
            None,
            true,
        ),
    );
    let d3: Vec<u8> = x
        .iter()
        .flat_map(|v| ((v * 8_388_607.0).round() as i32).to_le_bytes()[..3].to_vec())
        .collect();
    let p3 = write(
        dir.path(),
        "a24.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 3, 24, Some((24, 0, 1))), None),
                (b"data", d3, None),
            ],
            None,
            true,
        ),
    );
    let a = importers::load(&p16, &rig, &no_opts()).unwrap();
    for p in [&p24, &pf, &p3] {
        let b = importers::load(p, &rig, &no_opts()).unwrap();
        assert_eq!(b.len(), 3000);
        let worst = a.channels[0]
            .samples
            .iter()
            .zip(&b.channels[0].samples)
            .map(|(u, v)| (u - v).abs())
            .fold(0f32, f32::max);
        assert!(
            worst < 1e-4,
            "{}: differs from the 16-bit copy by {worst}",
            p.display()
        );
    }
    let b = importers::load(&p24, &rig, &no_opts()).unwrap();
    let notes = b.provenance.notes.join("; ");
    assert_mentions(
        &notes,
        &[
            "int24 in 32-bit containers",
            "WAVE_FORMAT_EXTENSIBLE",
            "channel mask 0x4",
        ],
    );
    // An unknown sub-format and more valid bits than the container are refused by name.
    let bad = write(
        dir.path(),
        "alaw.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 4, 32, Some((32, 4, 6))), None),
                (b"data", vec![0; 16], None),
            ],
            None,
            true,
        ),
    );
    assert_mentions(
        &err_of(importers::load(&bad, &rig, &no_opts())),
        &["alaw.wav", "sub-format", "not"],
    );
    let bad = write(
        dir.path(),
        "valid.wav",
        &riff(
            &[
                (b"fmt ", fmt_chunk(1, 2, 16, Some((24, 4, 1))), None),
                (b"data", vec![0; 16], None),
            ],
            None,
            true,
        ),
    );
    assert_mentions(
        &err_of(importers::load(&bad, &rig, &no_opts())),
        &["valid.wav", "24 valid bits", "16-bit"],
    );
}

#[test]
fn lying_and_unusual_wav_headers_are_read_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let rig = mono_rig("");
    let x = mono_signal(1000);
    let data = pcm16(&x);
    let fmt = || (b"fmt ", fmt_chunk(1, 2, 16, None), None);
    let warned = |r: &Recording, what: &str| {
        r.provenance
            .notes
            .iter()
            .any(|n| n.starts_with(importers::WARNING) && n.contains(what))
    };
    // A data size smaller than the data: read as declared, and said.
    let short = write(
        dir.path(),
        "short.wav",
        &riff(&[fmt(), (b"data", data.clone(), Some(1200))], None, true),
    );
    let r = importers::load(&short, &rig, &no_opts()).unwrap();
    assert_eq!(r.len(), 600);
    assert!(
        warned(&r, "800 more bytes follow"),
        "{:?}",
        r.provenance.notes
    );
    // The streaming reader (`import`, `replay`) says the same.
    let s = importers::open(&short, &rig, &no_opts()).unwrap();
    assert!(s
        .info()
        .provenance
        .notes
        .iter()
        .any(|n| n.contains("understate")));
    // A valid odd-sized chunk with its pad byte is read.
    let odd = write(
        dir.path(),
        "odd.wav",
        &riff(
            &[
                fmt(),
                (b"note", b"odd-sized".to_vec(), None),
                (b"data", data.clone(), None),
            ],
            None,
            true,
        ),
    );
    assert_eq!(importers::load(&odd, &rig, &no_opts()).unwrap().len(), 1000);
    // ...and one whose writer left the pad byte out.
    let nopad = write(
        dir.path(),
        "nopad.wav",
        &riff(
            &[
                fmt(),
                (b"note", b"odd-sized".to_vec(), None),
                (b"data", data.clone(), None),
            ],
            None,
            false,
        ),
    );
    assert_eq!(
        importers::load(&nopad, &rig, &no_opts()).unwrap().len(),
        1000
    );
    // Unfinalised headers (sizes 0 or 0xFFFFFFFF): the data to the end of the file, said.
    for (name, size) in [("zero.wav", 0u32), ("ffff.wav", u32::MAX)] {
        let p = write(
            dir.path(),
            name,
            &riff(
                &[fmt(), (b"data", data.clone(), Some(size))],
                Some(size),
                true,
            ),
        );
        let r = importers::load(&p, &rig, &no_opts()).unwrap();
        assert_eq!(r.len(), 1000, "{name}");
        assert!(
            warned(&r, "never finalised"),
            "{name}: {:?}",
            r.provenance.notes
        );
        assert_eq!(
            r.channels[0].samples[999],
            (x[999] * 32767.0).round() as f32 / 32768.0
        );
    }
    // A data size beyond the file is still truncation; RIFX and RF64 are refused by name.
    let long = write(
        dir.path(),
        "long.wav",
        &riff(&[fmt(), (b"data", data.clone(), Some(4000))], None, true),
    );
    assert_mentions(
        &err_of(importers::load(&long, &rig, &no_opts())),
        &["long.wav", "truncated", "2000 frames"],
    );
    let mut rifx = std::fs::read(&odd).unwrap();
    rifx[..4].copy_from_slice(b"RIFX");
    let rifx = write(dir.path(), "rifx.wav", &rifx);
    assert_mentions(
        &err_of(importers::load(&rifx, &rig, &no_opts())),
        &["rifx.wav", "big-endian RIFX"],
    );
}

/// `rigmon <args>` under `ulimit -v` (KiB): (exit code, stderr).
fn rigmon_limited(limit_kib: u64, args: &[&str]) -> (i32, String) {
    let o = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {limit_kib}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_rigmon"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn mat_bombs_are_refused_by_the_memory_estimate_not_aborted() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mat { be: false };
    // 128 MiB of int8 zeros in a ~130 KiB file: decoding takes 13 bytes per element.
    let n: u32 = 128 << 20;
    let int8 = m.compressed(&m.numeric("x", 8, 1, [n, 1], &vec![0u8; n as usize]));
    let p8 = write(dir.path(), "int8.mat", &m.file(&[int8]));
    assert!(std::fs::metadata(&p8).unwrap().len() < 1 << 20);
    // A struct whose field is a cell declaring 2^24 elements (zero bytes where they should be).
    let cells: u32 = 1 << 24;
    let mut cell = m.head(1, &[cells, 1], "");
    cell.extend(vec![0u8; 8 * cells as usize]);
    let s = m.compressed(&m.structure("s", &[("x", m.el(14, &cell))]));
    let pc = write(dir.path(), "cell.mat", &m.file(&[s]));
    let rig_file = |name: &str, extra: &str| {
        write(
            dir.path(),
            name,
            format!(
                "[machine]\nid = \"one\"\n[bearing]\nballs = 9\nball_diameter_mm = 7.94\npitch_diameter_mm = 39.04\n\
                 [acquisition]\nsample_rate_hz = 12000.0\n[[channels]]\nname = \"vertical\"\nkind = \"acceleration\"\n\
                 axis = \"vertical\"\nunit = \"g\"\n{extra}[speed]\nsource = \"fixed\"\nrpm = 1800.0\n[features]\nclassifier_axis = \"vertical\"\n"
            )
            .as_bytes(),
        )
    };
    let r1 = rig_file("one.toml", "");
    let r2 = rig_file("one-s.toml", "mat_variable = \"s.x\"\n");
    let out = dir.path().join("out.mcap");
    for (p, r) in [(&p8, &r1), (&pc, &r2)] {
        let (code, err) = rigmon_limited(
            1_000_000,
            &[
                "import",
                p.to_str().unwrap(),
                "--rig",
                r.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
        );
        assert_eq!(code, 1, "{}: {err}", p.display());
        assert_mentions(
            &err,
            &[p.to_str().unwrap(), "needs about", "available", "RLIMIT_AS"],
        );
    }
    // Without a limit the cell's header reserves nothing: its first element is refused at once.
    let e = err_of(importers::load(
        &pc,
        &RigConfig::load(&r2).unwrap(),
        &no_opts(),
    ));
    assert_mentions(&e, &["cell.mat", "expected a nested matrix"]);
}

#[test]
fn mat_names_rates_and_values_that_would_mislead_are_refused_in_bounded_messages() {
    let dir = tempfile::tempdir().unwrap();
    let m = Mat { be: false };
    let v = signal(500, 2.0);
    // A rate variable declaring 64 M characters is refused from its header, not decoded
    // (its data here says "12000": read whole, it was taken as the rate).
    let mut b = m.head(4, &[1, 64 << 20], "fs");
    b.extend(
        m.el(
            4,
            &"12000"
                .encode_utf16()
                .flat_map(u16::to_le_bytes)
                .collect::<Vec<u8>>(),
        ),
    );
    let p = write(
        dir.path(),
        "rate.mat",
        &m.file(&[m.double("x", 500, 1, &v), m.el(14, &b)]),
    );
    let rig = mono_rig("mat_rate_variable = \"fs\"\n");
    let e = err_of(importers::load(&p, &rig, &no_opts()).map(|r| r.sample_rate));
    assert_mentions(&e, &["rate.mat", "1x67108864 char", "expected one number"]);
    // Two variables of one name: which is meant cannot be told.
    let p = write(
        dir.path(),
        "dup.mat",
        &m.file(&[m.double("x", 500, 1, &v), m.double("x", 500, 1, &v)]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &mono_rig(""), &no_opts())),
        &["dup.mat", "two variables are named x"],
    );
    // Terminal escapes in names are shown escaped; a 30000-character name gives a short message.
    let long = "n".repeat(30_000);
    let p = write(
        dir.path(),
        "names.mat",
        &m.file(&[
            m.double("a\u{1b}[2Jb", 500, 1, &v),
            m.double(&long, 500, 1, &v),
        ]),
    );
    let e = err_of(importers::load(&p, &mono_rig(""), &no_opts()));
    assert!(!e.contains('\u{1b}'), "a raw escape in: {e:?}");
    assert_mentions(&e, &["a\\u{1b}[2Jb", "(30000 characters)"]);
    assert!(e.len() < 8000, "{} characters", e.len());
    // 1e300 is named as the number the file holds, not as the inf it would become.
    let mut big = v.clone();
    big[7] = 1e300;
    let p = write(
        dir.path(),
        "big.mat",
        &m.file(&[m.double("x", 500, 1, &big)]),
    );
    assert_mentions(
        &err_of(importers::load(&p, &mono_rig(""), &no_opts())),
        &["big.mat", "sample 7", "1e300", "range"],
    );
}

#[test]
fn no_command_writes_over_its_input_through_a_hard_link() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(shipped("lut-outer_race-588rpm.mcap")).unwrap();
    let cut = &bytes[..bytes.len() / 2];
    let (inp, link) = (dir.path().join("in.mcap"), dir.path().join("link.mcap"));
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/lut-rig.toml");
    let rigs = rig.to_str().unwrap();
    let (i, l) = (inp.to_str().unwrap(), link.to_str().unwrap());
    let rig_link = dir.path().join("rig-link.toml");
    std::fs::copy(&rig, dir.path().join("rig.toml")).unwrap();
    std::fs::hard_link(dir.path().join("rig.toml"), &rig_link).unwrap();
    let rl = dir.path().join("rig.toml");
    let cases: Vec<Vec<&str>> = vec![
        vec!["repair", i, "-o", l],
        vec!["import", i, "--rig", rigs, "-o", l],
        vec![
            "simulate",
            "--rig",
            rl.to_str().unwrap(),
            "--rpm",
            "600",
            "-o",
            rig_link.to_str().unwrap(),
        ],
        vec!["inspect", i, "--rig", rigs, "--png", l],
        vec!["trend", i, "--rig", rigs, "--png", l],
    ];
    for args in cases {
        std::fs::write(&inp, cut).unwrap();
        let _ = std::fs::remove_file(&link);
        std::fs::hard_link(&inp, &link).unwrap();
        let before = std::fs::read(dir.path().join("rig.toml")).unwrap();
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_rigmon"))
            .args(&args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert_mentions(
            &err,
            &["that is the input", "hard link", "write to another path"],
        );
        assert_eq!(
            std::fs::read(&inp).unwrap(),
            cut,
            "{args:?} changed its input"
        );
        assert_eq!(
            std::fs::read(dir.path().join("rig.toml")).unwrap(),
            before,
            "{args:?}"
        );
    }
}

#[test]
fn csv_times_must_be_finite_and_a_wide_header_costs_linear_time_and_no_memory() {
    let dir = tempfile::tempdir().unwrap();
    let rig = mono_rig("");
    // NaN (or inf) in the time column: refused with its line.
    let mut text = String::from("time,vertical\n");
    for i in 0..50 {
        let t = if i == 20 {
            "NaN".to_string()
        } else {
            format!("{}", i as f64 / 12000.0)
        };
        text += &format!("{t},{}\n", (i as f64 * 0.3).sin());
    }
    let p = write(dir.path(), "nan.csv", text.as_bytes());
    assert_mentions(
        &err_of(importers::load(&p, &rig, &no_opts())),
        &["nan.csv", "line 22", "\"time\"", "NaN", "finite"],
    );
    // 100 000 side-data columns and one channel: linear in the cells, side data not kept.
    let wide = 100_000;
    let mut text = String::from("vertical");
    for c in 0..wide {
        text += &format!(",side{c}");
    }
    text.push('\n');
    let row = format!("0.5{}\n", ",0".repeat(wide));
    for _ in 0..40 {
        text += &row;
    }
    let p = write(dir.path(), "wide.csv", text.as_bytes());
    let t0 = std::time::Instant::now();
    let r = importers::load(&p, &rig, &no_opts()).unwrap();
    assert_eq!(r.len(), 40);
    assert!(
        t0.elapsed().as_secs_f64() < 5.0,
        "{:?} for a wide header",
        t0.elapsed()
    );
    assert!(r.provenance.notes.iter().map(|n| n.len()).max().unwrap() < 3000);
    // 24 MB of `0` side data: peak memory stays near the text, not 4-8x it as f64 columns.
    let mut text = String::from("vertical");
    for c in 0..20 {
        text += &format!(",side{c}");
    }
    text.push('\n');
    let row = "0.25,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0\n";
    let rows = (24 << 20) / row.len();
    text.reserve(rows * row.len());
    for _ in 0..rows {
        text += row;
    }
    let p = write(dir.path(), "side.csv", text.as_bytes());
    let rig_path = write(
        dir.path(),
        "one.toml",
        toml::to_string(&rig).unwrap().as_bytes(),
    );
    let out = dir.path().join("side.mcap");
    let (code, _, err, rss_kb) = run_measured(&[
        "import",
        p.to_str().unwrap(),
        "--rig",
        rig_path.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let mb = rss_kb as f64 / 1024.0;
    assert!(
        mb < 24.0 * 2.5 + 40.0,
        "import of a 24 MB CSV peaked at {mb:.0} MB"
    );
}
