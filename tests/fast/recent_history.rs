//! A daemon's recent history over real Zenoh on loopback: a query by run and seq gets the
//! windows the ring still holds and then the daemon's word on what it holds
//! ([`rigmon::publish::recent::Held`], an error reply), so a historian can tell a window
//! dropped on the way (ask again) from one the ring no longer has (lost).

use crate::daemon::free_port;
use rigmon::publish::recent::{Held, RecentHistory, SUFFIX};
use rigmon::publish::zenoh::ZenohSettings;
use rigmon::vocabulary::ZenohMode;
use std::collections::BTreeSet;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;
use zenoh::Wait;

/// A window as the ring indexes it: `seq`, and an end time that puts it in run `run_ns`.
fn window(seq: u64, run_ns: u64) -> Vec<u8> {
    let end_s = seq as f64 * 0.5;
    format!(
        r#"{{"seq":{seq},"window":{{"end_s":{end_s},"end_ns":{}}}}}"#,
        run_ns + (end_s * 1e9) as u64
    )
    .into_bytes()
}

/// Ask `selector`; the seqs of the windows that came, and the word (if any).
fn ask(s: &zenoh::Session, selector: &str) -> (BTreeSet<u64>, Option<Held>) {
    let replies = s
        .get(selector)
        .consolidation(zenoh::query::ConsolidationMode::None)
        .timeout(Duration::from_secs(5))
        .wait()
        .unwrap();
    let (mut seqs, mut held) = (BTreeSet::new(), None);
    while let Ok(r) = replies.recv() {
        match r.result() {
            Ok(sample) => {
                let v: serde_json::Value =
                    serde_json::from_slice(&sample.payload().to_bytes()).unwrap();
                seqs.insert(v["seq"].as_u64().unwrap());
            }
            Err(e) => held = Held::parse(&e.payload().to_bytes()),
        }
    }
    (seqs, held)
}

#[test]
fn a_query_by_run_and_seq_ends_with_what_the_ring_holds() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let router = ZenohSettings {
        mode: ZenohMode::Router,
        listen: vec![endpoint.clone()],
        history_windows: 0,
        ..Default::default()
    }
    .open()
    .unwrap();
    let client = || {
        ZenohSettings {
            mode: ZenohMode::Client,
            connect: vec![endpoint.clone()],
            history_windows: 0,
            ..Default::default()
        }
        .open()
        .unwrap()
    };
    let (daemon, historian) = (client(), client());
    let base = "rigmon/word-rig/shaft/nde";
    let ring = RecentHistory::declare(&daemon, base, 3, Arc::new(AtomicU64::new(0)))
        .unwrap()
        .unwrap();
    let run = 1_700_000_000_000_000_000u64;
    for seq in 1..=5 {
        ring.push(&window(seq, run));
    }
    // the queryable reaches the historian's side through the router
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while ask(&historian, &format!("{base}/{SUFFIX}")).0.is_empty() {
        assert!(
            std::time::Instant::now() < deadline,
            "the ring never answered"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let (seqs, held) = ask(
        &historian,
        &format!("{base}/{SUFFIX}?run={run};seq=[2..4]|[6..9]"),
    );
    assert_eq!(
        seqs,
        [3, 4].into(),
        "window 2 left the ring of 3; 6-9 never made"
    );
    let held = held.expect("the daemon's word ends a query by run and seq");
    assert_eq!((held.run_start_ns, held.seqs), (run, Some((3, 5))));
    assert!(!held.holds(2) && held.holds(4) && !held.holds(6));

    let other = run + 5_000_000_000;
    let (seqs, held) = ask(
        &historian,
        &format!("{base}/{SUFFIX}?run={other};seq=[1..3]"),
    );
    assert!(seqs.is_empty());
    assert_eq!(held.map(|h| h.seqs), Some(None), "nothing of another run");

    let (seqs, held) = ask(&historian, &format!("{base}/{SUFFIX}"));
    assert_eq!(seqs, [3, 4, 5].into());
    assert_eq!(held, None, "a plain query gets the windows only");
    drop(ring);
    for s in [daemon, historian, router] {
        s.close().wait().unwrap();
    }
}
