//! `rbprops`: utilities around the pipeline — format conversion, campaigns, summaries
//! and reports.

use anyhow::{bail, Context};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(name = "rbprops", version, about = "rbprops utilities")]
struct Args {
    #[command(subcommand)]
    command: Command,
    /// Replace an output path that is not a previous rbprops output (a non-empty
    /// directory that is not a CSV run, a file of another kind). Never an input.
    #[arg(long, global = true)]
    force: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Convert a run between MCAP, a CSV directory and UFF (format from the paths;
    /// `-` or no input reads MCAP from stdin, no output writes MCAP to stdout).
    Convert(ConvertArgs),
    /// Run every campaign spec (*.toml), recording (*.mcap, CSV run directory) and UFF export
    /// (*.uff, *.unv, *.58, *.58b) under DIR through modal-fit | ni-select | rb-solve (and a
    /// model check when the campaign file names a nominal spec), in parallel, and write one
    /// summary table (CSV; stdout unless -o). Options come from DIR/campaign.toml or
    /// --config FILE (band_hz, method, modes, uncertainty, window_time_constant_s, nominal,
    /// geometry). Split over machines: `--shard K/N -o SHARD` on each, then
    /// `rbprops campaign merge SHARD... -o OUT`.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Campaign(CampaignArgs),
    /// Write a campaign spec (the TOML frf-sim and model-check read) from a recording:
    /// sensors, channels, excitations and set-ups with the recording's ids; body, suspension
    /// and damping as placeholders marked `FILL IN`.
    InitSpec(InitSpecArgs),
    /// Plan a test: the sensors and hits that best determine the ten properties
    /// (predicted by linear propagation of the spec's FRF noise through modal-fit,
    /// ni-select and rb-solve), written as a spec ready for frf-sim; with --evaluate, the
    /// predicted 95 % intervals of the spec's own layout, its weakest property and the
    /// sensor or hit that would help it most.
    Plan(PlanArgs),
    /// Summary rows (the campaign table's columns) of finished runs.
    Summary(SummaryArgs),
    /// A report of finished runs: one self-contained HTML page (`-o report.html`: the
    /// estimates with their intervals, every figure inline, the warnings grouped by stage
    /// and explained, the model check's verdict) or Markdown with SVG figures beside it
    /// (`-o DIR` writes DIR/report.md, `-o FILE.md` that file).
    Report(ReportArgs),
}

// The arguments of `rbprops convert`.
#[derive(clap::Args)]
struct ConvertArgs {
    input: Option<PathBuf>,
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// UFF input: list what the file holds (datasets, function types, nodes, units,
    /// frequency axes) instead of converting it.
    #[arg(long, requires = "input")]
    list: bool,
    #[command(flatten)]
    uff: rbprops_cli::UffArgs,
    #[command(flatten)]
    averages: rbprops_cli::AveragesArg,
    /// UFF input: write a channel map template (one row per dataset 58, known DOFs
    /// filled in) to this file instead of converting.
    #[arg(long, requires = "input")]
    channel_template: Option<PathBuf>,
    #[command(flatten)]
    checks: rbprops_cli::InputChecks,
}

// The arguments of `rbprops campaign`.
#[derive(clap::Args)]
struct CampaignArgs {
    #[command(subcommand)]
    action: Option<CampaignAction>,
    #[arg(required = true)]
    dir: Option<PathBuf>,
    /// The summary table (CSV; default stdout). With --shard: the shard's directory.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Run only shard K of N: the items i (0-based, in summary order) with
    /// i mod N = K − 1. Writes the directory -o SHARD (summary.csv, the manifest the
    /// merge reads, and with `--runs SHARD/runs` the items' runs).
    #[arg(long, value_name = "K/N", requires = "output")]
    shard: Option<rbprops_cli::shard::Shard>,
    /// Campaign file (TOML; default DIR/campaign.toml when it exists).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Standard errors as rb-solve computes them: `bootstrap` (100 replicates, seed 0,
    /// as rb-solve) or `linearised` (faster). Default: the campaign file's, else bootstrap.
    #[arg(long, value_enum)]
    uncertainty: Option<rbprops_cli::stages::UncertaintyChoice>,
    /// Also write each item's run (`DIR/<label>/run.mcap`, every stage's topic) and its
    /// figures (SVG) under DIR, for `rbprops report`: put it beside the summary as
    /// `runs/` (`-o OUT/summary.csv --runs OUT/runs`, then `rbprops report OUT`).
    #[arg(long)]
    runs: Option<PathBuf>,
    /// List every item's warnings (default: one line per stage, plus the warnings
    /// that change an answer).
    #[arg(short, long)]
    verbose: bool,
}

// The arguments of `rbprops init-spec`.
#[derive(clap::Args)]
struct InitSpecArgs {
    /// The recording: MCAP file, CSV directory or UFF file.
    recording: PathBuf,
    /// Output file (default: stdout).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

// The arguments of `rbprops plan`.
#[derive(clap::Args)]
struct PlanArgs {
    /// Campaign spec (body, suspension, damping, noise, band; its sensors and hits are
    /// the input layout).
    spec: PathBuf,
    /// Candidates CSV `id,x_m,y_m,z_m,role,dx,dy,dz` (role sensor|hit|both; a hit's
    /// allowed force direction, one row per direction). Default: the spec's points,
    /// hits along ±x, ±y, ±z.
    #[arg(long)]
    candidates: Option<PathBuf>,
    /// Triaxial sensors to place.
    #[arg(long, default_value_t = 4)]
    sensors: usize,
    /// Hits to place.
    #[arg(long, default_value_t = 6)]
    hits: usize,
    /// Criterion: d (ln det of the relative covariance), a (its trace) or worst (the
    /// largest relative standard deviation).
    #[arg(long, default_value = "d")]
    criterion: String,
    /// Estimator whose spread is planned for: tn (Toivola–Nuutila) or bc (Bretl–Conti).
    #[arg(long, default_value = "tn")]
    estimator: String,
    /// Least distance between two sensors (m).
    #[arg(long, default_value_t = 0.0)]
    min_spacing: f64,
    /// Judge the spec's own layout instead of planning one.
    #[arg(long)]
    evaluate: bool,
    /// Output format of the intervals: table or json.
    #[arg(long, default_value = "table")]
    format: String,
    /// Planned spec (default: stdout, the table then goes to stderr).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Write the layout in three views (SVG: body box, candidates, sensors, hits with
    /// their directions) into this directory.
    #[arg(long)]
    plot: Option<PathBuf>,
}

// The arguments of `rbprops summary`.
#[derive(clap::Args)]
struct SummaryArgs {
    /// Runs holding an estimates topic (MCAP or CSV directories).
    runs: Vec<PathBuf>,
    /// Campaign label (default: the file name).
    #[arg(long)]
    campaign: Option<String>,
    /// Mode-set label.
    #[arg(long, default_value = "ni")]
    set: String,
    /// Origin label.
    #[arg(long, default_value = "geometry")]
    origin: String,
}

// The arguments of `rbprops report`.
#[derive(clap::Args)]
struct ReportArgs {
    /// Summary CSV files (from `campaign` or `summary`); or, for HTML, one campaign
    /// output directory (summary.csv, and runs/ from `campaign --runs`), one run
    /// directory (run.mcap and the stages' `--plot` figures) or one run (MCAP/CSV).
    #[arg(required = true)]
    summaries: Vec<PathBuf>,
    /// Output: FILE.html, FILE.md or a directory (Markdown).
    #[arg(short, long)]
    output: PathBuf,
    #[arg(long, default_value = "rbprops report")]
    title: String,
    /// Extra figures (SVG files already written) to link in the report.
    #[arg(long)]
    figure: Vec<PathBuf>,
}

#[derive(Subcommand)]
enum CampaignAction {
    /// Merge the directories of `rbprops campaign DIR --shard K/N -o SHARD` (every K of one
    /// N, once each) into OUT: summary.csv and runs/ byte for byte as one machine writes
    /// them (`rbprops campaign DIR -o OUT/summary.csv [--runs OUT/runs]`), for
    /// `rbprops report OUT`. Warnings, counts and exit status as the single run's.
    Merge {
        /// The shards' directories.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
        /// Output directory (summary.csv, runs/).
        #[arg(short, long)]
        output: PathBuf,
        /// List every item's warnings.
        #[arg(short, long)]
        verbose: bool,
    },
}

fn main() -> std::process::ExitCode {
    rbprops_cli::run("rbprops", || {
        let args = Args::parse();
        rbprops_formats::atomic::set_force(args.force);
        command(args.command)
    })
}

/// One function per subcommand.
fn command(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Convert(a) => convert(a),
        Command::Campaign(CampaignArgs {
            action:
                Some(CampaignAction::Merge {
                    shards,
                    output,
                    verbose,
                }),
            ..
        }) => merge_shards(&shards, &output, verbose),
        Command::Campaign(a) => campaign(a),
        Command::InitSpec(a) => init_spec(a),
        Command::Plan(a) => plan(a),
        Command::Summary(a) => summary(a),
        Command::Report(a) => report(a),
    }
}

/// `rbprops convert`: a run to another format, or (`--list`, `--channel-template`) what
/// a UFF file or time-history recording holds.
fn convert(a: ConvertArgs) -> anyhow::Result<()> {
    if a.list || a.channel_template.is_some() {
        let path = a.input.as_deref().expect("clap requires the input");
        let uff = if rbprops_cli::is_time_history_recording(path) {
            rbprops_cli::read_time_histories(path)?.data
        } else {
            rbprops_cli::parse_uff(path)?
        };
        if let Some(t) = &a.channel_template {
            rbprops_cli::write_text(t, &rbprops_uff::channel_map_template(&uff))?;
        }
        if a.list {
            rbprops_cli::out(&format!("{}\n", rbprops_uff::inventory(&uff)))?;
        }
        return Ok(());
    }
    let mut inp = rbprops_cli::read_stage_input(
        "rbprops convert",
        a.input.as_deref(),
        &a.checks,
        &a.uff.options(),
    )?;
    rbprops_cli::variance::declare_averages(&mut inp.record, a.averages.averages, &inp.name)?;
    rbprops_cli::write_output(&inp.record, a.output.as_deref())
}

/// `rbprops campaign merge`: the shards' directories into one campaign output.
fn merge_shards(shards: &[PathBuf], output: &Path, verbose: bool) -> anyhow::Result<()> {
    let m = rbprops_cli::shard::merge(shards, output)?;
    for l in m.warnings.lines(verbose) {
        rbprops_cli::say!("rbprops campaign: {l}");
    }
    finish_campaign(
        &format!("merged {} shards", shards.len()),
        m.campaign.items.len(),
        m.rows,
        m.failed,
        m.checks_failed,
        m.campaign.model_check,
    )
}

/// The campaign's options: from `--config`, else DIR's campaign file when it exists,
/// else the defaults (the named files include the campaign file itself).
fn campaign_options(
    dir: &Path,
    config: Option<PathBuf>,
    uncertainty: Option<rbprops_cli::stages::UncertaintyChoice>,
) -> anyhow::Result<rbprops_cli::campaign::CampaignOptions> {
    let config = config.or_else(|| {
        let p = dir.join(rbprops_cli::campaign::CONFIG_FILE);
        p.exists().then_some(p)
    });
    let (cfg, base, source) = match &config {
        Some(p) => (
            rbprops_cli::campaign::CampaignConfig::read(p)?,
            p.parent().map(PathBuf::from).unwrap_or_default(),
            p.display().to_string(),
        ),
        None => (
            Default::default(),
            dir.to_path_buf(),
            "defaults".to_string(),
        ),
    };
    let mut opts = cfg.resolve(&base, &source, uncertainty)?;
    opts.named_files.extend(config);
    Ok(opts)
}

/// The items' provenance: the campaign's command line without its outputs.
fn record_campaign_provenance(a: &CampaignArgs, dir: &Path) {
    let mut recorded = vec!["campaign".to_string(), dir.display().to_string()];
    if let Some(c) = &a.config {
        recorded.extend(["--config".into(), c.display().to_string()]);
    }
    if let Some(u) = a
        .uncertainty
        .and_then(|u| clap::ValueEnum::to_possible_value(&u))
    {
        recorded.extend(["--uncertainty".into(), u.get_name().to_string()]);
    }
    rbprops_cli::set_provenance_args(recorded);
}

/// `rbprops campaign DIR`: every item under DIR, or one shard of them.
fn campaign(a: CampaignArgs) -> anyhow::Result<()> {
    let dir = a
        .dir
        .clone()
        .expect("clap requires DIR without a subcommand");
    record_campaign_provenance(&a, &dir);
    let opts = campaign_options(&dir, a.config, a.uncertainty)?;
    if let (Some(_), Some(out)) = (a.shard, &a.output) {
        rbprops_cli::shard::check_shard_paths(&dir, out, a.runs.as_deref())?;
    }
    let items = rbprops_cli::campaign::discover(&dir, &opts.named_files)?;
    if items.is_empty() {
        bail!(
            "{}: no campaign specs (*.toml), recordings (*.mcap, CSV runs) or UFF exports (*.uff, *.unv, *.58, *.58b) found",
            dir.display()
        );
    }
    let pb = rbprops_cli::progress(items.len() as u64, "campaign");
    let (res, what, n_items) = match (a.shard, &a.output) {
        (Some(shard), Some(out)) => {
            let id =
                rbprops_cli::shard::CampaignIdentity::new(&dir, &items, &opts, a.runs.is_some())?;
            let res = rbprops_cli::shard::run_shard(shard, &dir, &items, &opts, id, out, &pb)?;
            (
                res,
                format!("shard {shard} of {} items", items.len()),
                shard.indices(items.len()).len(),
            )
        }
        _ => {
            let res = rbprops_cli::campaign::run_all(&items, &dir, &opts, a.runs.as_deref(), &pb);
            let csv = rbprops_cli::summary::to_csv(&res.rows)?;
            match &a.output {
                Some(p) => rbprops_cli::write_text(p, &csv)?,
                None => rbprops_cli::out(&csv)?,
            }
            (res, "campaign".to_string(), items.len())
        }
    };
    pb.finish_and_clear();
    for l in res.warnings.lines(a.verbose) {
        rbprops_cli::say!("rbprops campaign: {l}");
    }
    finish_campaign(
        &what,
        n_items,
        res.rows.len(),
        res.failed,
        res.checks_failed,
        !opts.nominal.is_empty(),
    )
}

/// `rbprops init-spec`: a campaign spec with the recording's ids.
fn init_spec(a: InitSpecArgs) -> anyhow::Result<()> {
    let inp = rbprops_cli::read_input(Some(&a.recording))?;
    let (geometry, frf) = inp
        .record
        .require_geometry_and_frf()
        .with_context(|| inp.name.clone())?;
    let name = a
        .recording
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "recording".into());
    let text = rbprops_cli::init_spec::spec_text(&geometry, frf, &inp.name, &name)?;
    match &a.output {
        Some(p) => rbprops_cli::write_text(p, &text),
        None => rbprops_cli::out(&text),
    }
}

/// `rbprops plan`: the options read, the planning in `rbprops_cli::plan`.
fn plan(a: PlanArgs) -> anyhow::Result<()> {
    let criterion = match a.criterion.to_ascii_lowercase().as_str() {
        "d" => rbprops_plan::Criterion::D,
        "a" => rbprops_plan::Criterion::A,
        "worst" => rbprops_plan::Criterion::Worst,
        other => bail!("--criterion '{other}': expected d, a or worst"),
    };
    let estimator = match a.estimator.to_ascii_lowercase().as_str() {
        "tn" | "toivola_nuutila" => rbprops_plan::Estimator::ToivolaNuutila,
        "bc" | "bretl_conti" => rbprops_plan::Estimator::BretlConti,
        other => bail!("--estimator '{other}': expected tn or bc"),
    };
    let json = match a.format.as_str() {
        "json" => true,
        "table" => false,
        other => bail!("--format '{other}': expected table or json"),
    };
    if a.min_spacing.is_nan() || a.min_spacing < 0.0 {
        bail!("--min-spacing must be a distance ≥ 0");
    }
    rbprops_cli::plan::run(&rbprops_cli::plan::PlanArgs {
        spec: &a.spec,
        candidates: a.candidates.as_deref(),
        sensors: a.sensors,
        hits: a.hits,
        criterion,
        estimator,
        output: a.output.as_deref(),
        evaluate: a.evaluate,
        json,
        min_spacing_m: a.min_spacing,
        plot: a.plot.as_deref(),
    })
}

/// `rbprops summary`: the summary rows of finished runs, on stdout.
fn summary(a: SummaryArgs) -> anyhow::Result<()> {
    let mut rows = Vec::new();
    for r in &a.runs {
        let inp = rbprops_cli::read_input(Some(r))?;
        let label = a.campaign.clone().unwrap_or_else(|| {
            r.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
        rows.extend(
            rbprops_cli::summary::rows(&inp.record, &label, &a.set, &a.origin)
                .with_context(|| r.display().to_string())?,
        );
    }
    rbprops_cli::out(&rbprops_cli::summary::to_csv(&rows)?)
}

/// `rbprops report`: one HTML page from one input, or Markdown from summaries.
fn report(a: ReportArgs) -> anyhow::Result<()> {
    let ext = a
        .output
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if matches!(ext.as_deref(), Some("html") | Some("htm")) {
        return html_report(&a);
    }
    let mut rows = Vec::new();
    let mut hits = Vec::new();
    for s in &a.summaries {
        let data = rbprops_cli::report::load(s, &a.title)?;
        rows.extend(data.rows);
        hits.extend(data.runs.into_iter().map(|r| (r.label, r.hits)));
    }
    let (dir, md) = if ext.as_deref() == Some("md") {
        (
            a.output.parent().map(PathBuf::from).unwrap_or_default(),
            a.output
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
        )
    } else {
        (a.output.clone(), "report.md".to_string())
    };
    rbprops_cli::report::write(&dir, &md, &a.title, &rows, &a.figure, &hits)
}

/// `rbprops report INPUT -o FILE.html`: the page with the extra figures inline.
fn html_report(a: &ReportArgs) -> anyhow::Result<()> {
    let [input] = a.summaries.as_slice() else {
        bail!("an HTML report takes one input (a campaign output directory, a run directory or a summary CSV); got {}", a.summaries.len());
    };
    let mut data = rbprops_cli::report::load(input, &a.title)?;
    for f in &a.figure {
        let svg = rbprops_cli::read_text(f)?;
        let name = f
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        data.figures.push((name, svg));
    }
    rbprops_cli::report::write_html(&a.output, &data)
}

/// The campaign's last stderr line, and its failure when items or checks failed (after
/// the output was written: the table says why).
fn finish_campaign(
    what: &str,
    items: usize,
    rows: usize,
    failed: usize,
    checks_failed: usize,
    model_check: bool,
) -> anyhow::Result<()> {
    rbprops_cli::say!(
        "rbprops: {what}: {items} items, {rows} rows, {failed} failed{}",
        if model_check {
            format!(", {checks_failed} model checks failed")
        } else {
            String::new()
        }
    );
    if failed > 0 || checks_failed > 0 {
        bail!(
            "{failed} of {items} items failed, {checks_failed} model checks failed (rows with method 'error' or a check_verdict 'error: …' say why)"
        );
    }
    Ok(())
}
