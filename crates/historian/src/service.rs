//! The historian as a service: Zenoh intake -> bounded buffer (memory, spill) -> the write
//! loop (parse, gap tracking, batched COPY transactions, reconnects with backoff), beside it
//! the recovery task, the history queryable and the status: published every
//! `status_every_s`, sent to systemd as STATUS=, with READY=1 once subscribed and the
//! watchdog petted only while the write loop turns. SIGTERM: stop taking messages, write what
//! is buffered while the database answers (up to 15 s), spill the rest to disk, exit.

use super::audit::Auditor;
use super::buffer::{Batch, Buffer, Incoming, Kind};
use super::config::HistorianConfig;
use super::database::Target;
use super::latency::LatencyHistogram;
use super::recovery::{Missing, Tracker};
use super::row::WindowRow;
use super::status::{self, Counters, HistorianStatus, Phase};
use super::streams::Streams;
use super::writer::{is_connection_error, StatusRow, Writer};
use super::{admit, history, intake, point_config, recovery};
use anyhow::{anyhow, Context, Result};
use rigmon_runtime::daemon::notify::Notifier;
use rigmon_runtime::daemon::signals;
use rigmon_runtime::publish::time_range::now_ns;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::mpsc::{unbounded_channel, UnboundedSender};

/// How the caller runs the service.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// React to SIGTERM/SIGINT (the CLI).
    pub use_signals: bool,
    /// Stop flag for library callers.
    pub stop: Arc<AtomicBool>,
}

/// Everything the tasks share.
struct Shared {
    cfg: HistorianConfig,
    target: Target,
    buffer: Arc<Buffer>,
    counters: Arc<Counters>,
    /// The recovery plan: gaps in (write loop), requests out (recovery task).
    missing: Arc<Missing>,
    latency: Mutex<LatencyHistogram>,
    /// ms since start at the write loop's last turn.
    heartbeat_ms: AtomicU64,
    /// Stop taking new work; write what is buffered and return.
    draining: AtomicBool,
    /// Stop writing at once; return the batch in hand.
    abandon: AtomicBool,
    started: Instant,
    /// `started` as ns since the Unix epoch (the recovery's [`Tracker::listening_since`]).
    started_unix_ns: u64,
}

/// Run until stopped; returns the last status.
pub fn run(cfg: HistorianConfig, opts: RunOptions) -> Result<HistorianStatus> {
    cfg.zenoh_config()?;
    let target = cfg.database.resolve()?;
    let spill_dir = (cfg.spill_max_bytes() > 0).then_some(cfg.buffer.spill_dir.as_path());
    let counters = Arc::new(Counters::default());
    let buffer = Arc::new(
        Buffer::open(
            cfg.buffer.memory_messages,
            cfg.memory_max_bytes(),
            spill_dir,
            cfg.spill_max_bytes(),
        )?
        .with_ledger(counters.losses.clone()),
    );
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .thread_name("rigmon-historian")
        .build()
        .context("cannot start the tokio runtime")?;
    let missing = Arc::new(Missing::new(cfg.recovery.pacing()));
    let shared = Arc::new(Shared {
        cfg,
        target,
        buffer,
        counters,
        missing,
        latency: Mutex::default(),
        heartbeat_ms: AtomicU64::new(0),
        draining: AtomicBool::new(false),
        abandon: AtomicBool::new(false),
        started: Instant::now(),
        started_unix_ns: std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64),
    });
    if opts.use_signals {
        signals::install();
    }
    rt.block_on(serve(shared, opts))
}

async fn serve(sh: Arc<Shared>, opts: RunOptions) -> Result<HistorianStatus> {
    let cfg = &sh.cfg;
    let prefix = cfg.zenoh.key_prefix.clone();
    let session = open_session(cfg).await?;
    let (buffer, counters, max) = (
        sh.buffer.clone(),
        sh.counters.clone(),
        cfg.max_message_bytes(),
    );
    let subscribers = intake::subscribe(&session, &prefix, buffer, counters, max).await?;
    let status_pub = session
        .declare_publisher(cfg.status_key())
        .await
        .map_err(|e| anyhow!("declaring {}: {e}", cfg.status_key()))?;
    let tasks = Tasks::spawn(&sh, &session, &prefix);
    tracing::info!(
        "historian {}: subscribed to {prefix}/**/{{health,status}} (zenoh {} connect {:?}), writing to {}, status on {}",
        cfg.name, cfg.zenoh.mode, cfg.zenoh.connect, sh.target.describe(), cfg.status_key()
    );
    let mut notifier = Notifier::from_env();
    notifier.ready(&snapshot(&sh, Phase::Running).systemd_line());
    let watchdog = notifier
        .watchdog_interval()
        .unwrap_or(Duration::from_secs(5));
    let every = Duration::from_secs_f64(cfg.status_every_s);
    let mut last_status = Instant::now() - every;
    loop {
        if opts.stop.load(Ordering::SeqCst) || (opts.use_signals && signals::stop_requested()) {
            break;
        }
        if last_status.elapsed() >= every {
            let s = snapshot(&sh, Phase::Running);
            if let Err(e) = status_pub.put(serde_json::to_vec(&s)?).await {
                tracing::debug!("publishing the historian status: {e}");
            }
            notifier.status(&s.systemd_line());
            sh.counters.losses.log_new();
            last_status = Instant::now();
        }
        let beat = sh.heartbeat_ms.load(Ordering::Relaxed);
        if (sh.started.elapsed().as_millis() as u64).saturating_sub(beat)
            < watchdog.as_millis() as u64
        {
            notifier.progress();
        }
        notifier.tick(false);
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    notifier.stopping("stopping: writing what is buffered");
    drop(subscribers);
    sh.draining.store(true, Ordering::SeqCst);
    let _ = status_pub
        .put(serde_json::to_vec(&snapshot(&sh, Phase::Stopping))?)
        .await;
    let pending = drain(&sh, tasks.writer).await;
    let unkept = sh.buffer.persist(pending);
    if unkept > 0 {
        tracing::warn!("{unkept} buffered messages could not be kept (no spill folder): the daemons' recent history has them for the next start");
    }
    tasks.history.abort();
    tasks.recovery.abort();
    tasks.audit.abort();
    sh.counters.losses.log_new();
    let last = snapshot(&sh, Phase::Finished);
    let _ = status_pub.put(serde_json::to_vec(&last)?).await;
    drop(status_pub);
    let _ = session.close().await;
    Ok(last)
}

/// The historian's tasks beside the status loop.
struct Tasks {
    recovery: tokio::task::JoinHandle<()>,
    history: tokio::task::JoinHandle<anyhow::Result<()>>,
    writer: tokio::task::JoinHandle<Vec<Incoming>>,
    audit: tokio::task::JoinHandle<()>,
}

impl Tasks {
    fn spawn(sh: &Arc<Shared>, session: &zenoh::Session, prefix: &str) -> Tasks {
        let cfg = &sh.cfg;
        Tasks {
            recovery: tokio::spawn(recovery::run(
                session.clone(),
                prefix.to_string(),
                sh.missing.clone(),
                sh.buffer.clone(),
                sh.counters.clone(),
                cfg.recovery.clone(),
            )),
            history: tokio::spawn(history::serve(
                session.clone(),
                prefix.to_string(),
                sh.target.clone(),
                cfg.history.max_replies,
                sh.counters.clone(),
            )),
            writer: tokio::spawn(write_loop(sh.clone(), session.clone())),
            audit: tokio::spawn(
                Auditor {
                    target: sh.target.clone(),
                    buffer: sh.buffer.clone(),
                    counters: sh.counters.clone(),
                    missing: sh.missing.clone(),
                    settings: cfg.recovery.clone(),
                    batch_rows: cfg.batch.max_rows as u64,
                    listening_since_ns: sh.started_unix_ns,
                }
                .run(),
            ),
        }
    }
}

/// Wait for the write loop to write what is buffered (up to 15 s); if it is still writing
/// then, let it finish the batch in hand (a write gives up after 30 s) and take that batch
/// back, so it goes to the spill rather than being lost.
async fn drain(sh: &Shared, mut writer: tokio::task::JoinHandle<Vec<Incoming>>) -> Vec<Incoming> {
    match tokio::time::timeout(Duration::from_secs(15), &mut writer).await {
        Ok(Ok(p)) => p,
        Ok(Err(_)) => Vec::new(),
        Err(_) => {
            sh.abandon.store(true, Ordering::SeqCst);
            match tokio::time::timeout(Duration::from_secs(35), writer).await {
                Ok(Ok(p)) => p,
                _ => Vec::new(),
            }
        }
    }
}

async fn open_session(cfg: &HistorianConfig) -> Result<zenoh::Session> {
    zenoh::open(cfg.zenoh_config()?).await.map_err(|e| {
        anyhow!(
            "cannot open a zenoh session (mode {}, connect {:?}): {e}",
            cfg.zenoh.mode,
            cfg.zenoh.connect
        )
    })
}

/// The status now.
fn snapshot(sh: &Shared, phase: Phase) -> HistorianStatus {
    let c = &sh.counters;
    let g = Counters::get;
    let level = sh.buffer.level();
    HistorianStatus {
        schema: status::SCHEMA.into(),
        schema_version: status::SCHEMA_VERSION,
        name: sh.cfg.name.clone(),
        time_ns: now_ns(),
        uptime_s: sh.started.elapsed().as_secs_f64(),
        phase,
        database: status::DatabaseStatus {
            target: sh.target.describe().to_string(),
            connected: c.db_connected.load(Ordering::Relaxed),
            reconnects: g(&c.db_reconnects),
            schema_version: c.schema_version.load(Ordering::Relaxed),
            last_error: c.last_error.lock().ok().and_then(|e| e.clone()),
            last_commit_ns: g(&c.last_commit_ns),
        },
        received: status::Received {
            health: g(&c.received_health),
            status: g(&c.received_status),
            rejected: g(&c.rejected),
            refused: status::Refused {
                key: g(&c.refused_key),
                name: g(&c.refused_name),
                future: g(&c.refused_future),
                seq: g(&c.refused_seq),
                too_large: g(&c.refused_too_large),
            },
        },
        rows: status::Rows {
            committed: g(&c.committed_rows),
            duplicates: g(&c.duplicate_rows),
            expired: g(&c.expired),
            events: g(&c.events),
            batches: g(&c.batches),
        },
        buffer: status::BufferStatus {
            memory: level.memory,
            spilled: level.spilled,
            spill_bytes: level.spill_bytes,
            spilled_total: g(&sh.buffer.counters.spilled_total),
            dropped: g(&sh.buffer.counters.dropped),
            memory_bytes: level.memory_bytes,
            spill_damaged: level.damaged,
            spill_damaged_bytes: level.damaged_bytes,
        },
        recovery: status::Recovery {
            gaps: g(&c.gaps),
            requested: g(&c.requested),
            recovered: g(&c.recovered),
            lost: g(&c.lost),
            backfilled: g(&c.backfilled),
            not_backfilled: g(&c.not_backfilled),
            late: g(&c.late),
            asked_again: g(&c.asked_again),
            waiting: sh.missing.level().0,
            in_flight: sh.missing.level().1,
            audits: g(&c.audits),
            audit_found: g(&c.audit_found),
            auditing: c.auditing.load(Ordering::Relaxed),
        },
        latency: sh.latency.lock().map(|h| h.summary()).unwrap_or_default(),
        history: status::HistoryAnswers {
            queries: g(&c.queries_answered),
            rows_sent: g(&c.history_rows_sent),
        },
        software_version: env!("CARGO_PKG_VERSION").to_string(),
        lost: c.losses.summary(match phase {
            Phase::Finished => usize::MAX,
            _ => super::losses::STATUS_RANGES,
        }),
        profile: c.profile(),
    }
}

/// A batch taken from the buffer, parsed once (and retried as is until written).
struct Pending {
    batch: Batch,
    rows: Vec<WindowRow>,
    statuses: Vec<StatusRow>,
    /// publish_time_ns of the live rows, for the latency.
    live_publish_ns: Vec<u64>,
}

/// Parse a batch: bad messages, refused ones ([`admit`]) and expired rows are counted and
/// left out; live windows go through the gap tracker.
fn parse(sh: &Shared, batch: Batch, tracker: &mut Tracker) -> Pending {
    let t0 = Instant::now();
    let now = now_ns();
    let horizon =
        now.saturating_sub(u64::from(sh.cfg.retention.windows_days) * 86_400 * 1_000_000_000);
    let rules = sh.cfg.admission();
    let mut p = Pending {
        rows: Vec::new(),
        statuses: Vec::new(),
        live_publish_ns: Vec::new(),
        batch: Batch {
            messages: Vec::new(),
            origin: batch.origin,
        },
    };
    for m in &batch.messages {
        match m.kind {
            Kind::Health => match WindowRow::parse(&m.payload, &sh.cfg.default_site) {
                Ok(r) if r.end_ns < horizon => Counters::add(&sh.counters.expired, 1),
                Ok(r) if refuse(sh, m, admit::window(&rules, &m.key, &r, now)) => {}
                Ok(r) => {
                    if !m.recovered {
                        track(sh, tracker, &r);
                        p.live_publish_ns.push(r.publish_ns);
                    }
                    p.rows.push(r);
                }
                Err(e) => reject(sh, m, &e),
            },
            Kind::Status => match StatusRow::parse(&m.payload) {
                Ok(s) if refuse(sh, m, admit::status(&rules, &m.key, &s, now)) => {}
                Ok(s) => p.statuses.push(s),
                Err(e) => reject(sh, m, &e),
            },
        }
    }
    p.batch = batch;
    Counters::time(&sh.counters.decode_ns, t0);
    p
}

/// A live window through the gap tracker: a gap it opens goes into the recovery plan, a
/// window older than its point's newest (late, out of order) comes out of it.
/// Every second at most, while the historian keeps up: ask the tail of every point gone
/// silent ([`Tracker::silent_tails`]).
fn ask_silent_tails(sh: &Shared, tracker: &mut Tracker, last_scan: &mut Instant) {
    // only while the historian keeps up (nothing spilled, at most one batch waiting): with
    // a backlog a point's newer windows may wait in the buffer (a silence of the tracker,
    // not of the point), and asking their tails would only bring back what it holds
    let level = sh.buffer.level();
    let backlog = level.spilled > 0 || level.memory > sh.cfg.batch.max_rows as u64;
    if last_scan.elapsed() < Duration::from_secs(1) || !sh.cfg.recovery.enabled || backlog {
        return;
    }
    *last_scan = Instant::now();
    let n = sh.cfg.recovery.pacing().max_windows;
    for g in tracker.silent_tails(crate::recovery::TAIL_SILENCE, n) {
        sh.missing.gap(g);
    }
}

fn track(sh: &Shared, tracker: &mut Tracker, r: &WindowRow) {
    let key = r.point.key();
    let late = tracker.is_late(&key, r.run_start_ns, r.seq);
    if let Some(g) = tracker.observe(&key, r.run_start_ns, r.seq) {
        Counters::add(&sh.counters.gaps, 1);
        sh.missing.gap(g);
    } else if late {
        sh.missing.arrived(&key, r.run_start_ns, r.seq);
    }
}

/// True (counted by reason, logged) when admission refused the message.
fn refuse(sh: &Shared, m: &Incoming, verdict: Result<(), admit::Refused>) -> bool {
    let Err((why, text)) = verdict else {
        return false;
    };
    let n = sh.counters.refused(why).fetch_add(1, Ordering::Relaxed) + 1;
    if n <= 3 || n.is_power_of_two() {
        tracing::warn!(
            "message on {} refused ({}, {n} so far): {text}",
            m.key,
            why.as_str()
        );
    }
    true
}

fn reject(sh: &Shared, m: &Incoming, e: &anyhow::Error) {
    let n = sh.counters.rejected.fetch_add(1, Ordering::Relaxed) + 1;
    if n <= 3 || n.is_power_of_two() {
        tracing::warn!("message on {} skipped ({n} so far): {e:#}", m.key);
    }
}

/// Wait for work: a full batch, or the oldest message waiting `max_delay`.
async fn gather(sh: &Shared) -> bool {
    let max_delay = Duration::from_millis(sh.cfg.batch.max_delay_ms);
    if sh.buffer.is_empty() {
        let _ = tokio::time::timeout(Duration::from_millis(500), sh.buffer.notify.notified()).await;
        if sh.buffer.is_empty() {
            return false;
        }
    }
    let t0 = Instant::now();
    while t0.elapsed() < max_delay
        && (sh.buffer.level().memory as usize) < sh.cfg.batch.max_rows
        && sh.buffer.level().memory_bytes < sh.cfg.batch_max_bytes()
        && sh.buffer.level().spilled == 0
    {
        tokio::time::sleep(Duration::from_millis(10).min(max_delay)).await;
    }
    true
}

/// The write loop; returns the messages it could not write when told to stop.
async fn write_loop(sh: Arc<Shared>, session: zenoh::Session) -> Vec<Incoming> {
    let (limits_tx, mut limits_rx) = unbounded_channel::<(i32, [f64; 3])>();
    let mut writer: Option<Streams> = None;
    let mut tracker: Option<Tracker> = None;
    let mut pending: Option<Pending> = None;
    let mut backoff = Duration::from_millis(250);
    let mut last_retention: Option<Instant> = None;
    let mut last_tail_scan = Instant::now();
    loop {
        sh.heartbeat_ms
            .store(sh.started.elapsed().as_millis() as u64, Ordering::Relaxed);
        let draining = sh.draining.load(Ordering::SeqCst);
        if sh.abandon.load(Ordering::SeqCst) {
            return pending.map(|p| p.batch.messages).unwrap_or_default();
        }
        if writer.as_ref().is_some_and(|w| w.is_closed()) {
            note_down(
                &sh,
                &anyhow!("the connection to {} was closed", sh.target.describe()),
            );
            Counters::add(&sh.counters.db_reconnects, 1);
            writer = None;
        }
        if writer.is_none() {
            match connect(&sh).await {
                Ok((w, seed)) => {
                    tracker = Some(reseeded(seed, pending.as_ref(), &sh));
                    writer = Some(w);
                    backoff = Duration::from_millis(250);
                }
                Err(e) => {
                    if draining {
                        return pending.map(|p| p.batch.messages).unwrap_or_default();
                    }
                    note_down(&sh, &e);
                    sleep_beating(&sh, backoff).await;
                    backoff = (backoff * 2).min(Duration::from_secs(5));
                    continue;
                }
            }
        }
        let Some(w) = writer.as_mut() else { continue };
        if last_retention.is_none_or(|t| t.elapsed() > Duration::from_secs(3600)) {
            if let Err(e) = w
                .first()
                .retention(sh.cfg.retention.windows_days, sh.cfg.retention.minutes_days)
                .await
            {
                tracing::warn!("retention: {e:#}");
            }
            last_retention = Some(Instant::now());
        }
        while let Ok((id, limits)) = limits_rx.try_recv() {
            let _ = w.first().set_iso_limits(id, limits).await;
        }
        if let Some(t) = tracker.as_mut() {
            ask_silent_tails(&sh, t, &mut last_tail_scan);
        }
        if pending.is_none() {
            if !gather(&sh).await {
                if draining {
                    return Vec::new();
                }
                continue;
            }
            let t0 = Instant::now();
            let batch = sh
                .buffer
                .take(sh.cfg.batch.max_rows, sh.cfg.batch_max_bytes());
            Counters::time(&sh.counters.take_ns, t0);
            let t = tracker
                .get_or_insert_with(|| Tracker::default().listening_since(sh.started_unix_ns));
            pending = Some(parse(&sh, batch, t));
        }
        let Some(p) = pending.as_mut() else { continue };
        let t0 = Instant::now();
        let result =
            tokio::time::timeout(Duration::from_secs(30), w.write(&mut p.rows, &p.statuses)).await;
        Counters::time(&sh.counters.write_ns, t0);
        match result {
            Ok(Ok(outcome)) => {
                committed(&sh, p, &outcome);
                ask_limits(&sh, &session, &limits_tx, outcome.new_points);
                sh.buffer.commit(&p.batch);
                pending = None;
            }
            Ok(Err(e)) if !is_connection_error(&e, w.is_closed()) => {
                tracing::warn!(
                    "a batch of {} rows was refused ({e:#}); writing its rows one by one",
                    p.rows.len()
                );
                write_each(&sh, w.first(), p).await;
                sh.buffer.commit(&p.batch);
                pending = None;
            }
            outcome => {
                let e = match outcome {
                    Ok(Err(e)) => e,
                    _ => anyhow!("the database did not answer within 30 s"),
                };
                note_down(&sh, &e);
                Counters::add(&sh.counters.db_reconnects, 1);
                writer = None;
            }
        }
    }
}

/// The gap tracker after a (re)connect: where each point stands in the database, then the
/// batch still waiting to be written. A commit the database acknowledged and then lost (it
/// crashed within `synchronous_commit = off`'s window, see [`Writer::open`]) shows up as a
/// gap when the point's next window arrives, and is asked of its daemon like any other.
fn reseeded(
    seed: std::collections::HashMap<String, (u64, u64)>,
    pending: Option<&Pending>,
    sh: &Shared,
) -> Tracker {
    let mut t = Tracker::seeded(seed).listening_since(sh.started_unix_ns);
    for r in pending.map_or(&[][..], |p| &p.rows) {
        track(sh, &mut t, r);
    }
    t
}

/// Ask each new point's daemon for its ISO 20816-3 zone limits (stored when they come).
fn ask_limits(
    sh: &Shared,
    session: &zenoh::Session,
    limits: &UnboundedSender<(i32, [f64; 3])>,
    new_points: Vec<(i32, String)>,
) {
    for (id, key) in new_points {
        let (s, prefix, tx) = (
            session.clone(),
            sh.cfg.zenoh.key_prefix.clone(),
            limits.clone(),
        );
        tokio::spawn(async move {
            if let Some(l) = point_config::iso_limits(&s, &prefix, &key).await {
                let _ = tx.send((id, l));
            }
        });
    }
}

/// Open a writer and read where each point stands in the database.
async fn connect(
    sh: &Arc<Shared>,
) -> Result<(Streams, std::collections::HashMap<String, (u64, u64)>)> {
    let b = &sh.cfg.batch;
    let (mut w, version) = Streams::open(&sh.target, b.streams, b.synchronous_commit).await?;
    w.load_points().await?;
    let seed = w.first().last_positions().await?;
    sh.counters
        .schema_version
        .store(i64::from(version), Ordering::Relaxed);
    sh.counters.db_connected.store(true, Ordering::Relaxed);
    sh.counters.set_error(None);
    tracing::info!(
        "writing to PostgreSQL {} (schema version {version})",
        sh.target.describe()
    );
    Ok((w, seed))
}

fn note_down(sh: &Shared, e: &anyhow::Error) {
    let was_up = sh.counters.db_connected.swap(false, Ordering::Relaxed);
    let text = format!("{e:#}");
    if was_up
        || sh
            .counters
            .last_error
            .lock()
            .map(|g| g.as_deref() != Some(&text))
            .unwrap_or(true)
    {
        tracing::warn!("database unavailable, buffering: {text}");
    }
    sh.counters.set_error(Some(text));
}

async fn sleep_beating(sh: &Shared, d: Duration) {
    let end = Instant::now() + d;
    while Instant::now() < end {
        sh.heartbeat_ms
            .store(sh.started.elapsed().as_millis() as u64, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_millis(100).min(end - Instant::now())).await;
    }
}

fn committed(sh: &Shared, p: &Pending, o: &super::writer::Outcome) {
    let c = &sh.counters;
    Counters::add(&c.committed_rows, o.inserted);
    Counters::add(&c.duplicate_rows, o.duplicates);
    Counters::add(&c.events, o.events);
    Counters::add(&c.batches, 1);
    let now = now_ns();
    c.last_commit_ns.store(now, Ordering::Relaxed);
    if let Ok(mut h) = sh.latency.lock() {
        for &t in &p.live_publish_ns {
            h.add((now as f64 - t as f64) / 1e9);
        }
    }
}

/// A refused batch, row by row: the rows the database refuses are counted and skipped.
async fn write_each(sh: &Shared, w: &mut Writer, p: &mut Pending) {
    let mut total = super::writer::Outcome::default();
    for r in p.rows.drain(..) {
        let key = format!("{} seq {}", r.point.key(), r.seq);
        let mut one = [r];
        match w.write(&mut one, &[]).await {
            Ok(o) => {
                total.inserted += o.inserted;
                total.duplicates += o.duplicates;
                total.events += o.events;
            }
            Err(e) => {
                Counters::add(&sh.counters.rejected, 1);
                tracing::warn!("window {key} refused by the database: {e:#}");
            }
        }
    }
    committed(sh, p, &total);
}
