//! The checker can fail: each fault planted in the model's harness (never
//! in the product) is found, as a shortest counterexample to the invariant
//! it breaks, whose timeline shows what the fault did.

use fbwag_model::{check, CheckOptions, Fault, ModelConfig};

fn finds(fault: Fault, invariant: &str, last_words: &str) {
    let opts = CheckOptions {
        model: ModelConfig::for_fault(fault),
        depth: Some(14),
        stop_at_first: true,
        ..CheckOptions::default()
    };
    let report = check(opts, |_, _| {});
    let v = report
        .violations
        .iter()
        .find(|v| v.invariant == invariant)
        .unwrap_or_else(|| {
            panic!(
                "{}: no counterexample to {invariant}: {report:#?}",
                fault.name()
            )
        });
    assert!(
        v.trace.iter().all(|l| l.starts_with("t=")),
        "{:#?}",
        v.trace
    );
    assert!(
        v.trace.iter().any(|l| l.contains(last_words)),
        "{}: {:#?}",
        fault.name(),
        v.trace
    );
}

#[test]
fn control_applied_in_the_handshake_breaks_single_controller() {
    finds(
        Fault::ControlInHandshake,
        "single-controller",
        "harness: applies the control in handshake",
    );
}

#[test]
fn endless_retries_break_bounded_notices() {
    finds(
        Fault::EndlessRetries,
        "bounded-notices",
        "harness: re-sends the FC's notice",
    );
}

#[test]
fn a_stale_acknowledgement_after_a_reboot_breaks_no_stale_takeover() {
    finds(
        Fault::StaleAckAfterReboot,
        "no-stale-takeover",
        "FC: mode Companion",
    );
}
