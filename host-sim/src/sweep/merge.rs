//! `parapet sweep-merge`: join the shards of a sweep into one `sweep.csv`,
//! `sweep.json` and heatmaps, refusing inputs that do not belong together.
//!
//! The inputs' manifests are checked first ([`super::manifest::plan_merge`]:
//! identity, N, duplicates, missing shards), then the rows stream through a
//! k-way merge by grid index, each row checked against its input's manifest
//! (index in the input's shards and increasing, parameters those of the grid
//! point, row count). Memory: one row per input plus one record per heatmap cell.
//!
//! May import: the other `sweep` submodules, `crate::{cli, input}`, clap.

use std::collections::BinaryHeap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;

use super::grid::{Grid, Shard};
use super::heatmap::{self, Aggregator};
use super::manifest::{self, Identity, Manifest};
use super::record::{self, SweepRecord};
use super::{bad_input, create_out, output_files, refuse_overwrite, say, some_failed};
use crate::cli::exit_codes_help;
use crate::cli::CliError;
use crate::input::InputError;

fn merge_help() -> String {
    format!(
        "\
Inputs: shard directories of `parapet sweep --shard I/N`, or their sweep.csv files (sweep.json must
  be next to each). Refused (exit 2): shards of different sweeps (scene name or file contents, path,
  filter, noise, duration, μ/δ1/speed ranges, --grid axes, --param/--params values, seed count,
  parapet version), different N, a shard
  given twice, rows that do not match their manifest, missing shards (listed) unless --allow-partial.
  The output directory must not hold an input.

Examples:
  parapet sweep-merge out/s1 out/s2 --out out/fig9
  parapet sweep-merge out/s1/sweep.csv out/s3/sweep.csv --allow-partial

{}",
        exit_codes_help("some merged rows are failed runs (status failed in sweep.csv)")
    )
}

/// Options of `parapet sweep-merge`.
#[derive(Debug, Args)]
#[command(after_help = merge_help())]
pub struct SweepMergeArgs {
    /// Shard directories (or their sweep.csv files) of `parapet sweep --shard I/N`.
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Merge although some shards are missing (the output's sweep.json lists the shards it holds).
    #[arg(long)]
    pub allow_partial: bool,
    /// Output directory (sweep.csv, sweep.json and heatmaps); must not hold an input.
    #[arg(long, default_value = "out/sweep-merge")]
    pub out: PathBuf,
}

/// The manifest and CSV of a `sweep-merge` input (a directory or its sweep.csv).
fn input_files(p: &Path) -> (PathBuf, PathBuf) {
    if p.is_dir() {
        (p.join("sweep.csv"), p.join("sweep.json"))
    } else {
        (p.to_path_buf(), p.with_extension("json"))
    }
}

/// One input of a merge while it streams: its next row, for the heap.
struct Head {
    index: u64,
    input: usize,
    rec: SweepRecord,
}
impl PartialEq for Head {
    fn eq(&self, o: &Self) -> bool {
        self.index == o.index
    }
}
impl Eq for Head {}
impl PartialOrd for Head {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Head {
    // Reversed: BinaryHeap is a max-heap, the smallest index must come first.
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.index.cmp(&self.index)
    }
}

/// Reads one input's rows, checking each against its manifest: indices strictly
/// increasing and in the input's shards, parameters those of the grid point.
struct CheckedRows {
    rows: record::CsvRows,
    grid: Grid,
    identity: Identity,
    shard_count: u64,
    shards: Vec<u64>,
    last: Option<u64>,
    seen: u64,
}

impl CheckedRows {
    fn next(&mut self) -> Result<Option<SweepRecord>, InputError> {
        let Some((line, r)) = self.rows.next_record()? else { return Ok(None) };
        let at = format!("{}: line {line}", self.rows.file());
        let shard = r.index % self.shard_count + 1;
        if self.last.is_some_and(|l| r.index <= l) || self.shards.binary_search(&shard).is_err() {
            return Err(InputError::file(
                &at,
                format!(
                    "grid index out of order or not in this file's shards {:?} of {}",
                    self.shards, self.shard_count
                ),
            )
            .field("index")
            .value(r.index));
        }
        let p = self.grid.point(r.index);
        let same = p.mu.to_bits() == r.mu.to_bits()
            && p.delta1.to_bits() == r.delta1.to_bits()
            && p.speed.to_bits() == r.speed.to_bits()
            && p.seed == r.seed
            && p.params.len() == r.params.len()
            && p.params
                .iter()
                .zip(&r.params)
                .all(|(x, y)| super::grid::as_flown(*x as f32).to_bits() == y.to_bits())
            && r.scene == self.identity.scene
            && r.filter == self.identity.filter
            && r.noise == self.identity.noise;
        if !same {
            return Err(InputError::file(
                &at,
                format!(
                    "the row does not match grid point {} of its sweep.json (mu {}, delta1 {}, speed {}, seed {}, scene {}, filter {})",
                    r.index, p.mu, p.delta1, p.speed, p.seed, self.identity.scene, self.identity.filter
                ),
            )
            .field("index")
            .value(r.index));
        }
        self.last = Some(r.index);
        self.seen += 1;
        Ok(Some(r))
    }
}

/// Stream the k-way merge of `readers` into `path`; every input must end with
/// as many rows as its manifest (`named`) says.
fn merge_rows(
    readers: &mut [CheckedRows],
    named: &[(String, Manifest)],
    path: &Path,
    names: &[String],
) -> Result<Aggregator, CliError> {
    let mut csv =
        record::CsvSink::create(path, names).with_context(|| format!("cannot write {}", path.display()))?;
    let mut heap = BinaryHeap::new();
    for (k, r) in readers.iter_mut().enumerate() {
        if let Some(rec) = r.next().map_err(bad_input)? {
            heap.push(Head { index: rec.index, input: k, rec });
        }
    }
    let mut agg = Aggregator::default();
    while let Some(h) = heap.pop() {
        agg.add(&h.rec);
        csv.push(&h.rec).with_context(|| format!("cannot write {}", path.display()))?;
        if let Some(rec) = readers[h.input].next().map_err(bad_input)? {
            heap.push(Head { index: rec.index, input: h.input, rec });
        }
    }
    csv.finish().with_context(|| format!("cannot write {}", path.display()))?;
    for (r, (name, m)) in readers.iter().zip(named) {
        if r.seen != m.rows {
            return Err(bad_input(InputError::file(
                name,
                format!("has {} rows, its sweep.json says {} (truncated?)", r.seen, m.rows),
            )));
        }
    }
    Ok(agg)
}

/// `parapet sweep-merge`.
pub fn cmd_sweep_merge(a: SweepMergeArgs) -> Result<(), CliError> {
    let mut named = Vec::new();
    let mut files = Vec::new();
    for p in &a.inputs {
        let (csv, json) = input_files(p);
        if !csv.is_file() {
            return Err(bad_input(InputError::file(
                csv.display(),
                "no such file (a sweep.csv, or a directory with one)",
            )));
        }
        let m = Manifest::read(&json)
            .map_err(|e| bad_input(InputError::file(csv.display(), format!("its manifest: {e}"))))?;
        named.push((csv.display().to_string(), m));
        files.push(csv.clone());
        files.push(json);
    }
    let plan = manifest::plan_merge(&named).map_err(bad_input)?;
    if !plan.missing.is_empty() && !a.allow_partial {
        let n_missing = plan.shard_count - plan.present.len() as u64;
        let list: Vec<String> =
            plan.missing.iter().take(20).map(|i| format!("{i}/{}", plan.shard_count)).collect();
        return Err(bad_input(
            InputError::file(
                "sweep-merge",
                format!(
                    "{n_missing} of {} shards are missing: {}{} (merge them too, or pass --allow-partial)",
                    plan.shard_count,
                    list.join(", "),
                    if n_missing > 20 { ", …" } else { "" }
                ),
            )
            .value(format!("{} inputs", a.inputs.len())),
        ));
    }
    refuse_overwrite(&output_files(&a.out), &files, "out")?;
    let first = named[0].1.clone();
    let grid = first.identity.grid();
    let axis_names: Vec<String> = first.identity.grid_params.iter().map(|a| a.name.clone()).collect();
    let total = first.grid_runs;
    let mut readers = Vec::new();
    for (k, (name, m)) in named.iter().enumerate() {
        let expected: u64 =
            m.shards.iter().map(|&i| Shard { index: i, count: m.shard_count }.len(total)).sum();
        if expected != m.rows {
            return Err(bad_input(
                InputError::file(
                    format!("{}", files[2 * k + 1].display()),
                    "the row count does not match the shards",
                )
                .field("rows")
                .value(m.rows)
                .allowed(expected.to_string()),
            ));
        }
        let rows = record::CsvRows::open(Path::new(name), &axis_names).map_err(bad_input)?;
        readers.push(CheckedRows {
            rows,
            grid: grid.clone(),
            identity: m.identity.clone(),
            shard_count: m.shard_count,
            shards: m.shards.clone(),
            last: None,
            seen: 0,
        });
    }
    create_out(&a.out)?;
    let json = a.out.join("sweep.json");
    let csv_path = a.out.join("sweep.csv");
    // Rows go to a scratch file first: a merge refused half-way (a damaged input)
    // leaves the directory's previous outputs as they were.
    let scratch = a.out.join("sweep.csv.partial");
    let merged = merge_rows(&mut readers, &named, &scratch, &axis_names);
    let agg = match merged {
        Ok(agg) => agg,
        Err(e) => {
            let _ = std::fs::remove_file(&scratch);
            return Err(e);
        }
    };
    if json.exists() {
        std::fs::remove_file(&json).with_context(|| format!("cannot remove the old {}", json.display()))?;
    }
    std::fs::rename(&scratch, &csv_path).with_context(|| format!("cannot write {}", csv_path.display()))?;
    let complete = plan.missing.is_empty();
    let m = Manifest {
        identity: first.identity.clone(),
        scene_file: first.scene_file.clone(),
        path_file: first.path_file.clone(),
        grid_runs: total,
        shard_count: if complete { 1 } else { plan.shard_count },
        shards: if complete { vec![1] } else { plan.present.iter().map(|p| p.0).collect() },
        rows: agg.rows(),
        failed: agg.failed(),
    };
    m.write(&json).with_context(|| format!("cannot write {}", json.display()))?;
    let (_, warnings) = heatmap::write_heatmaps(&a.out, &first.identity.scene, &agg.aggregate());
    for w in warnings {
        eprintln!("warning: {w}");
    }
    say(format_args!(
        "merged {} inputs ({} of {} shards): {} of {} runs, {} failed -> {}",
        a.inputs.len(),
        plan.present.len(),
        plan.shard_count,
        agg.rows(),
        total,
        agg.failed(),
        csv_path.display()
    ));
    if !complete {
        eprintln!(
            "warning: partial merge (--allow-partial): {} of {} shards missing",
            plan.shard_count - plan.present.len() as u64,
            plan.shard_count
        );
    }
    some_failed(agg.failed(), agg.rows(), &csv_path)
}
