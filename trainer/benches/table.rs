//! Host time to read a logger's table, per line, against the csv crate's
//! own reader over the same text in the same run:
//!
//! - `table/parse`: [`Table::parse`] (separator, header, rows with their
//!   lines) on 100,000 lines of `t,theta` at 1 kHz, as an encoder logger
//!   writes them;
//! - `table_peer/csv_reader`: one `csv::Reader` over the same text, each
//!   record's fields copied out (what the table keeps).
//!
//! `cargo bench -p trainer --bench table` prints each time and the peer's
//! ratio to the table's.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::measurement::WallTime;
use criterion::{BenchmarkGroup, Criterion, Throughput};
use trainer_core::data::table::Table;

/// Lines of the text read.
const LINES: u64 = 100_000;

/// A logger's export: a header, then `t,theta` at 1 kHz of a 0.3 rad swing.
fn text() -> String {
    let mut s = String::from("t,theta\n");
    for k in 0..LINES {
        let t = k as f64 * 1e-3;
        s.push_str(&format!("{t:.3},{:.5}\n", 0.3 * (3.13 * t).cos()));
    }
    s
}

/// A criterion group with this bench's settings: per line of the text.
fn group<'c>(c: &'c mut Criterion, name: &str) -> BenchmarkGroup<'c, WallTime> {
    let mut g = c.benchmark_group(name);
    g.warm_up_time(Duration::from_secs(1));
    g.measurement_time(Duration::from_secs(3));
    g.sample_size(10);
    g.throughput(Throughput::Elements(LINES));
    g
}

fn bench(c: &mut Criterion) {
    let text = text();
    let mut g = group(c, "table");
    g.bench_function("parse", |b| {
        b.iter(|| Table::parse(Path::new("bench.csv"), black_box(&text)).map(|t| t.len()))
    });
    g.finish();
    let mut g = group(c, "table_peer");
    g.bench_function("csv_reader", |b| {
        b.iter(|| {
            let mut reader = csv::ReaderBuilder::new()
                .trim(csv::Trim::All)
                .flexible(true)
                .from_reader(black_box(text.as_bytes()));
            let rows: Vec<Vec<String>> = reader
                .records()
                .filter_map(Result::ok)
                .map(|r| r.iter().map(str::to_string).collect())
                .collect();
            rows.len()
        })
    });
    g.finish();
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    c.final_summary();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("../criterion");
    let read = |group: &str, name: &str| -> Option<f64> {
        let p = dir.join(group).join(name).join("new/estimates.json");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(p).ok()?).ok()?;
        v["mean"]["point_estimate"]
            .as_f64()
            .map(|ns| ns / LINES as f64)
    };
    if let (Some(table), Some(peer)) = (read("table", "parse"), read("table_peer", "csv_reader")) {
        println!(
            "per line: the table {table:.0} ns, one csv reader {peer:.0} ns (the table / the peer: {:.2})",
            table / peer
        );
    }
}
