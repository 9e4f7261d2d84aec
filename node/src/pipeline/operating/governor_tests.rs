//! The governor against scripted worker times: where it starts, when it moves down and up,
//! that it settles, the `auto` budget, and the extremes.

use super::governor::{Budget, Governor, GovernorConfig};
use super::table::{OperatingTable, TableRow};

/// Points `a` (best, 1000 ms), `b` (500 ms), `c` (200 ms), `d` (fastest, 50 ms).
fn table() -> OperatingTable {
    let row = |name: &str, ms: f64, psnr: f64| TableRow {
        point: crate::pipeline::operating::parse_points(&format!("[[point]]\nname = \"{name}\""))
            .unwrap()
            .remove(0),
        ms,
        psnr,
    };
    OperatingTable::new(
        (100, 100),
        String::new(),
        vec![
            row("c", 200.0, 20.0),
            row("a", 1000.0, 24.0),
            row("d", 50.0, 18.0),
            row("b", 500.0, 22.0),
        ],
    )
    .unwrap()
}

const A: usize = 0;
const B: usize = 1;
const C: usize = 2;
const D: usize = 3;

/// Runs `bins` bins where point `i` takes `ms[i]` times `slow`, returning the points chosen.
fn drive(g: &mut Governor, bins: usize, ms: [f64; 4], slow: f64) -> Vec<usize> {
    (0..bins)
        .map(|_| {
            let p = g.choose().point;
            g.record(p, (ms[p] * slow * 1e6) as i64, 0);
            p
        })
        .collect()
}

#[test]
fn it_starts_at_the_most_accurate_point_the_table_says_fits() {
    let t = table();
    let at = |ms: f64| Governor::new(&t, Budget::Fixed(ms), GovernorConfig::default()).current();
    assert_eq!(at(2000.0), A);
    assert_eq!(at(1000.0), B, "1000 ms is over 90% of a 1000 ms budget");
    assert_eq!(at(600.0), B);
    assert_eq!(at(300.0), C);
    assert_eq!(at(60.0), D);
}

#[test]
fn a_budget_no_point_fits_runs_the_fastest_and_counts_it() {
    let mut g = Governor::new(&table(), Budget::Fixed(10.0), GovernorConfig::default());
    let chosen = drive(&mut g, 6, [1000.0, 500.0, 200.0, 50.0], 1.0);
    assert_eq!(chosen, vec![D; 6]);
    assert_eq!(g.unfit_bins(), 6);
    assert_eq!(g.switches(), 0);
}

#[test]
fn a_slower_machine_moves_it_down_until_a_point_fits_and_then_it_stays() {
    // Everything takes 3x the table: b (1500 ms) misses an 800 ms budget, c (600 ms) fits.
    let mut g = Governor::new(&table(), Budget::Fixed(800.0), GovernorConfig::default());
    assert_eq!(g.current(), B);
    let chosen = drive(&mut g, 30, [1000.0, 500.0, 200.0, 50.0], 3.0);
    assert_eq!(&chosen[..2], &[B, C], "{chosen:?}");
    assert!(chosen[1..].iter().all(|&p| p == C), "{chosen:?}");
    assert_eq!(g.switches(), 1);
    assert_eq!(g.unfit_bins(), 0);
}

#[test]
fn room_moves_it_up_after_settling_and_hysteresis_keeps_it_there() {
    // Everything takes half the table: from d it may go up to b (250 ms) within 70% of a
    // 400 ms budget; a (500 ms) never fits.
    let mut g = Governor::new(&table(), Budget::Fixed(400.0), GovernorConfig::default());
    assert_eq!(g.current(), C);
    let chosen = drive(&mut g, 40, [1000.0, 500.0, 200.0, 50.0], 0.5);
    let settle = GovernorConfig::default().settle;
    assert!(chosen[..settle].iter().all(|&p| p == C), "{chosen:?}");
    assert!(chosen[settle..].iter().all(|&p| p == B), "{chosen:?}");
    assert_eq!(g.switches(), 1);
    // b at 250 ms of 400 is 62.5%: it fits (90%) but a is never tried (500 > 400).
    assert!(!chosen.contains(&A));
}

#[test]
fn times_between_the_thresholds_do_not_make_it_switch_back_and_forth() {
    // c takes 80% of the budget (fits, no room to go up); b would take 200% (never fits).
    let mut g = Governor::new(&table(), Budget::Fixed(250.0), GovernorConfig::default());
    let chosen = drive(&mut g, 50, [1000.0, 500.0, 200.0, 50.0], 1.0);
    assert!(chosen.iter().all(|&p| p == C), "{chosen:?}");
    assert_eq!(g.switches(), 0);
}

#[test]
fn renders_add_to_every_point_unscaled() {
    // Models at the table's times, renders 300 ms: from c (200 + 300 = 500 ms of 600, over
    // 70%) it may not go up to b (500 + 300 = 800), and d is expected at 350.
    let mut g = Governor::new(&table(), Budget::Fixed(600.0), GovernorConfig::default());
    assert_eq!(g.current(), B, "by the table alone b fits");
    for _ in 0..6 {
        let p = g.choose().point;
        g.record(p, (table().rows[p].ms * 1e6) as i64, 300_000_000);
    }
    assert_eq!(g.current(), C);
    assert_eq!(g.expected_ms(C), 500.0);
    assert_eq!(g.expected_ms(D), 350.0);
    assert_eq!(g.expected_ms(A), 1300.0);
}

#[test]
fn the_auto_budget_is_the_median_time_between_bin_openings() {
    let mut g = Governor::new(&table(), Budget::Auto, GovernorConfig::default());
    assert_eq!(g.budget_ms(), None);
    assert_eq!(
        g.choose().point,
        D,
        "the fastest until two bins have opened"
    );
    let t0 = 1_000_000_000_000;
    for at_ms in [0, 800, 1590, 2400, 7400, 8200] {
        g.bin_opened(t0 + at_ms * 1_000_000);
    }
    // Gaps 800, 790, 810, 5000, 800: the median ignores the stop.
    assert_eq!(g.budget_ms(), Some(800.0));
    // A clock step back starts the intervals over.
    g.bin_opened(t0);
    assert_eq!(g.budget_ms(), None);
}

#[test]
fn the_extremes_leave_it_on_a_point_of_the_table() {
    let t = table();
    for budget in [1e-300, 1e-9, 1e300, f64::MAX] {
        let mut g = Governor::new(&t, Budget::Fixed(budget), GovernorConfig::default());
        for ns in [0, -5, i64::MAX, i64::MIN, 1] {
            let p = g.choose().point;
            assert!(p < 4);
            g.record(p, ns, ns);
            g.record(99, ns, 0);
        }
        let e = g.expected_ms(g.current());
        assert!(e.is_finite() && e > 0.0, "{budget}: {e}");
    }
    let mut g = Governor::new(&t, Budget::Auto, GovernorConfig::default());
    for at in [i64::MIN, 0, i64::MAX] {
        g.bin_opened(at);
    }
    assert!(g.budget_ms().is_none_or(|b| b.is_finite()));
    assert!(g.choose().point < 4);
}
