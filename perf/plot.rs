//! `raypack-plot`: draws how build time and rays per second grow with the primitive
//! count, from the JSON files of `raypack bench --json`, into one PNG.
//!
//! Built only with the `plot` feature, so plotters stays out of the default build:
//!
//!     cargo run --release --features plot --bin raypack-plot -- \
//!         --out perf/scaling.png perf/scaling/*.json
//!
//! Each file is one scene (e.g. `spd:balls:5`); files whose scenes share a name before
//! the size (`spd:balls`) and were built by the same builder (`exact`, `fast`) form one
//! series. Left: build seconds against primitives
//! (log-log). Right: median Mrays/s against primitives (log x), one line per series, set
//! and mode, at the thread count given by `--threads` (default 1). Text is drawn with a
//! TrueType font (`--font`, default DejaVu Sans).

use anyhow::{Context, bail};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};
use std::collections::BTreeMap;
use std::path::PathBuf;

struct Args {
    out: PathBuf,
    font: PathBuf,
    threads: u64,
    inputs: Vec<PathBuf>,
}

fn parse_args() -> anyhow::Result<Args> {
    let mut args = Args {
        out: PathBuf::from("perf/scaling.png"),
        font: PathBuf::from("/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"),
        threads: 1,
        inputs: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        let mut value = |name: &str| it.next().with_context(|| format!("{name} needs a value"));
        match a.as_str() {
            "--out" => args.out = value("--out")?.into(),
            "--font" => args.font = value("--font")?.into(),
            "--threads" => args.threads = value("--threads")?.parse().context("--threads")?,
            "-h" | "--help" => {
                println!("raypack-plot [--out PNG] [--font TTF] [--threads N] BENCH.json...");
                std::process::exit(0);
            }
            _ if a.starts_with("--") => bail!("unknown option {a}"),
            _ => args.inputs.push(a.into()),
        }
    }
    if args.inputs.is_empty() {
        bail!("no input: give the JSON files of `raypack bench --json`");
    }
    Ok(args)
}

/// One bench file: series name, primitive count, build seconds, and the rates of the
/// wanted thread count by (set, mode).
struct Point {
    series: String,
    prims: f64,
    build: f64,
    rates: Vec<(String, f64)>,
}

fn read_point(path: &PathBuf, threads: u64) -> anyhow::Result<Point> {
    let text = std::fs::read_to_string(path).with_context(|| path.display().to_string())?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| path.display().to_string())?;
    let field = |k: &str| {
        v[k].as_f64()
            .with_context(|| format!("{}: no `{k}`", path.display()))
    };
    let scene = v["scene"].as_str().unwrap_or("?");
    let base = match scene.rsplit_once(':') {
        Some((head, size)) if size.parse::<u32>().is_ok() => head.trim_start_matches("spd:"),
        _ => scene,
    };
    // Files of `bench --builder B` form a series per builder.
    let series = match v["builder"].as_str() {
        Some(builder) => format!("{base} {builder}"),
        None => base.to_string(),
    };
    let rates = v["results"]
        .as_array()
        .with_context(|| format!("{}: no `results`", path.display()))?
        .iter()
        .filter(|r| r["threads"].as_u64() == Some(threads))
        .filter_map(|r| {
            let label = format!("{} {}", r["set"].as_str()?, r["mode"].as_str()?);
            Some((label, r["mrays_median"].as_f64()?))
        })
        .collect();
    Ok(Point {
        series,
        prims: field("primitives")?,
        build: field("build_seconds")?,
        rates,
    })
}

fn main() -> anyhow::Result<()> {
    let args = parse_args()?;
    let font = std::fs::read(&args.font).with_context(|| {
        format!(
            "{}: a TrueType font is needed (--font)",
            args.font.display()
        )
    })?;
    register_font(
        "sans-serif",
        FontStyle::Normal,
        Box::leak(font.into_boxed_slice()),
    )
    .map_err(|_| anyhow::anyhow!("{}: not a usable font", args.font.display()))?;

    let mut points = args
        .inputs
        .iter()
        .map(|p| read_point(p, args.threads))
        .collect::<anyhow::Result<Vec<_>>>()?;
    points.sort_by(|a, b| a.prims.total_cmp(&b.prims));
    let mut builds: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    let mut rates: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
    for p in &points {
        builds
            .entry(p.series.clone())
            .or_default()
            .push((p.prims, p.build));
        for (label, r) in &p.rates {
            rates
                .entry(format!("{} {label}", p.series))
                .or_default()
                .push((p.prims, *r));
        }
    }
    let (pmin, pmax) = (points[0].prims * 0.8, points[points.len() - 1].prims * 1.25);
    let bmin = points.iter().map(|p| p.build).fold(f64::INFINITY, f64::min) * 0.5;
    let bmax = points.iter().map(|p| p.build).fold(0.0, f64::max) * 2.0;
    let rmax = rates.values().flatten().map(|p| p.1).fold(0.0, f64::max) * 1.15;

    // Drawn to a temporary name and renamed, so the PNG is written whole or not at all.
    let tmp = args
        .out
        .with_extension(format!("tmp{}.png", std::process::id()));
    let root = BitMapBackend::new(&tmp, (1400, 560)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(700);
    let palette = |i: usize| Palette99::pick(i).to_rgba();

    let mut chart = ChartBuilder::on(&left)
        .caption("kd-tree build time", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d((pmin..pmax).log_scale(), (bmin.max(1e-6)..bmax).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("primitives")
        .y_desc("build seconds")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .y_label_formatter(&|y| format!("{y:.0e}"))
        .draw()?;
    for (i, (name, pts)) in builds.iter().enumerate() {
        let c = palette(i);
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()?;

    let mut chart = ChartBuilder::on(&right)
        .caption(
            format!("Mrays/s, {} thread(s), 1024x768 sets", args.threads),
            ("sans-serif", 22),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d((pmin..pmax).log_scale(), 0.0..rmax)?;
    chart
        .configure_mesh()
        .x_desc("primitives")
        .y_desc("Mrays/s (median)")
        .x_label_formatter(&|x| format!("{x:.0e}"))
        .draw()?;
    for (i, (name, pts)) in rates.iter().enumerate() {
        let c = palette(i + builds.len());
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))?
            .label(name.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled())))?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()?;
    root.present()
        .with_context(|| format!("writing {}", tmp.display()))?;
    drop(chart);
    drop(root);
    std::fs::rename(&tmp, &args.out).with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}
