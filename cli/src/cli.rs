//! Command-line definitions (clap derive), one struct per subcommand.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand, ValueEnum};
use forcemap_io::steps::unlabelled::DEFAULT_FREQUENCY_TOLERANCE;
use forcemap_math::identify::{Method, Weighting};

#[derive(Debug, Parser)]
#[command(
    name = "forcemap",
    version,
    about = "Frequency-domain force-state mapping for test rigs: identify nonlinear element parameters, reproduce the reference tables, simulate rigs."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Reproduce Tables 1-4 of Kim (1997): the paper's numbers, the truth and forcemap's
    /// (paper method and improved method) side by side.
    Reproduce(ReproduceArgs),
    /// Identify a model's parameters from measurements: bags, CSV exports, or (with
    /// --channels) a bench's own text, MAT, JSON, MDF4 or TDMS files.
    Identify(IdentifyArgs),
    /// Simulate the suspension rig or the 3-DOF example and write a test-bench CSV export.
    Simulate(SimulateArgs),
    /// What measured files hold and how forcemap cuts them: columns and units, the map's
    /// picks and conversions, the setup, and each record (kind, frequency, amplitude, rate,
    /// span); `--plot DIR` draws the drive with the records found.
    Info(InfoArgs),
    /// Inspect or repair rosbag2 MCAP bags.
    Bag(BagArgs),
    /// Import data into a bag.
    Import(ImportArgs),
    /// Diagnose the gap between a baseline model and measured data: how large, where, which
    /// unmodelled effect causes it and how far it shrinks once that effect is added.
    Diagnose(DiagnoseArgs),
    /// Check the gap diagnosis on simulated cases with withheld planted effects.
    DiagnoseEval(DiagnoseEvalArgs),
    /// List the named models.
    Models,
    /// Run one ROS 2 node (sensor, harmonic, identifier, recorder, monitor, diagnoser, foreign); settings are ROS
    /// parameters: `forcemap node identifier --ros-args -p model:=coulomb`.
    Node(NodeArgs),
    /// Start the nodes of a ROS 2 YAML launch file as separate processes:
    /// `forcemap launch launch_configs/rig_sim.launch.yaml out:=/tmp/run`.
    Launch(LaunchArgs),
    /// Benchmarks: the node graph (throughput without loss, latency, CPU and memory) and
    /// `identify` on a CSV export against its numpy peer.
    Bench(BenchArgs),
    /// Print a shell completion script: `forcemap completions bash > /etc/bash_completion.d/forcemap`.
    Completions(CompletionsArgs),
    /// Write the manual pages (forcemap.1 and one per subcommand) into a new directory.
    Man(ManArgs),
}

#[derive(Debug, Args)]
pub struct CompletionsArgs {
    /// The shell the script is for.
    #[arg(value_enum)]
    pub shell: clap_complete::Shell,
}

#[derive(Debug, Args)]
pub struct ManArgs {
    /// The directory to write the pages into (must not exist; written whole or not at all).
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,
}

#[derive(Debug, Args)]
pub struct InfoArgs {
    /// The files: bags, CSV exports, or (with --channels) text, MDF4, TDMS, MAT or JSON files of a
    /// bench's own columns; quoted glob patterns are expanded.
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// The channel map the files are read through (see docs/data.md).
    #[arg(long, value_name = "MAP")]
    pub channels: Option<PathBuf>,
    /// One JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Write `drive_N.svg` per file into this directory: the driven channel over time, each
    /// record found shaded and labelled.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: BenchCommand,
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Run the harmonic node and the identifier as processes, play a simulated rig run into
    /// them and measure samples/s without loss, last-sample-to-theta latency, CPU and RSS.
    Graph(BenchGraphArgs),
    /// Time `identify` on a rig CSV export stage by stage (CSV parsing, phasors, fit,
    /// validation; medians over repeats) with its throughput and peak memory and, with
    /// --python, a peer on the same file (polars loading it, or the numpy fit script), as a
    /// ratio.
    Identify(Box<BenchIdentifyArgs>),
}

#[derive(Debug, Args)]
pub struct BenchIdentifyArgs {
    /// The identification to time (file, --model, --method, ... as for `forcemap identify`).
    #[command(flatten)]
    pub identify: IdentifyArgs,
    /// A python to run the peer with (not run without it): with polars or numpy for the
    /// load peer (asammdf for an MDF4 file, npTDMS for a TDMS file), with numpy for the fit
    /// peer.
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// The peer: the time polars (else numpy; asammdf, npTDMS for MDF4, TDMS) needs to load
    /// the file (benches/load_peer.py), or the numpy script that loads and fits it
    /// (benches/numpy_peer.py).
    #[arg(long, value_enum, default_value_t = PeerArg::Load)]
    pub peer: PeerArg,
    /// Repeats of each side (medians reported).
    #[arg(long, default_value_t = 7)]
    pub repeats: usize,
}

/// What `bench identify --python` compares identify with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PeerArg {
    /// Loading the file into columns of floats (polars.read_csv, else numpy.loadtxt).
    Load,
    /// Loading and fitting the paper's first-harmonic equations with numpy.
    Fit,
}

#[derive(Debug, Args)]
pub struct BenchGraphArgs {
    /// Sine steps (the paper's 1.6-3.4 Hz, cycled).
    #[arg(long, default_value_t = 20)]
    pub steps: usize,
    #[arg(long, default_value_t = 100.0)]
    pub sample_rate_hz: f64,
    /// Duration of each step [s] (13 s is the paper's 1300 samples at 100 Hz).
    #[arg(long, default_value_t = 13.0)]
    pub step_duration_s: f64,
    /// 0: as fast as the graph acknowledges; 1: real time.
    #[arg(long, default_value_t = 0.0)]
    pub rate_factor: f64,
    /// Rigs in the graph, each in its own namespace (/rig1, /rig2, ...; /rig for one) with its
    /// own harmonic node and identifier, all fed the same run (a four-poster: 4).
    #[arg(long, default_value_t = 1)]
    pub rigs: usize,
    /// Also break the latency down stage by stage (the nodes mark each stage of a step's path
    /// to theta: DDS hops, assembly, analysis, solve, publishes).
    #[arg(long)]
    pub trace: bool,
    #[arg(long)]
    pub json: bool,
}

#[derive(Debug, Args)]
pub struct NodeArgs {
    /// sensor, harmonic, identifier, recorder, monitor, diagnoser or foreign.
    pub kind: String,
    /// ROS arguments: --ros-args -p name:=value --params-file FILE -r from:=to -r __ns:=/rig
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    pub ros_args: Vec<String>,
}

#[derive(Debug, Args)]
pub struct LaunchArgs {
    /// The launch file (ROS 2 YAML launch format).
    pub file: PathBuf,
    /// Launch arguments, name:=value.
    pub args: Vec<String>,
    /// Print the commands that would be started, and exit.
    #[arg(long)]
    pub dry_run: bool,
}

#[derive(Debug, Args)]
pub struct BagArgs {
    #[command(subcommand)]
    pub command: BagCommand,
}

#[derive(Debug, Subcommand)]
pub enum BagCommand {
    /// Summarise a bag directory or a bare .mcap: topics, types, counts, duration.
    Info {
        bag: PathBuf,
        /// One JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Rebuild a bag whose recorder died before writing the footer and summary, keeping every
    /// complete message.
    Recover {
        /// The damaged .mcap file, or the directory holding it.
        input: PathBuf,
        /// The new bag directory (must not exist).
        output: PathBuf,
    },
}

#[derive(Debug, Args)]
pub struct ReproduceArgs {
    /// One JSON object per row (JSON lines) instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Measurement SNR [dB] of the simulated rig stand-in (Tables 2-4).
    #[arg(long, default_value_t = 40.0)]
    pub rig_snr_db: f64,
    /// Seed of the simulated noise and random excitation.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Only these tables (1-4); all by default.
    #[arg(long, value_delimiter = ',')]
    pub tables: Vec<u8>,
}

#[derive(Debug, Args)]
pub struct IdentifyArgs {
    /// The data: bag directories or bare .mcap files, test-bench CSV exports, or (with
    /// --channels) text, MDF4, TDMS, MAT or JSON files of a bench's own columns; several files (or
    /// quoted glob patterns) are identified together, each keeping its own sample rate (see
    /// docs/data.md).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<PathBuf>,
    /// Model name (see `forcemap models`).
    #[arg(long)]
    pub model: String,
    /// fd (the paper's FD-FSM, first harmonic only), fd-multi (all harmonics, slip-phase
    /// aware), td (time-domain FSM, 20 points per step; td-N, td-all), output-error (fd-multi
    /// refined against the exact stick-slip simulation; rig, 3-DOF drive-point and element
    /// setups).
    #[arg(long, default_value = "fd-multi")]
    pub method: Method,
    /// Time points per step for --method td ("all" for every settled sample; default 20).
    #[arg(long)]
    pub td_points: Option<String>,
    /// How fd-multi weights its equations: robust (each harmonic by its measured noise plus
    /// the step's form error, estimated from the residual), noise (by its measured noise alone)
    /// or uniform.
    #[arg(long, default_value_t = Weighting::default())]
    pub weighting: Weighting,
    /// Track drifting parameters: weigh the steps so far by this factor each time a step is
    /// added (0 < F < 1; 0.8 is a window of about 4 steps); prints theta after every step.
    /// 1 (the default) converges over the whole run.
    #[arg(long, default_value_t = 1.0)]
    pub forgetting_per_step: f64,
    /// Track within each long step too: theta every T seconds of a step's samples once they
    /// have settled periods (the provisional phasors the live harmonic node publishes with
    /// `update_period_s: T`), each replaced by the next or by the step's final theta.
    #[arg(long, value_name = "T")]
    pub update_period_s: Option<f64>,
    /// Mass of the rig [kg] (overrides the params file).
    #[arg(long)]
    pub mass_kg: Option<f64>,
    /// Slope M [s/m] of the atan friction term (coulomb-atan models).
    #[arg(long)]
    pub atan_m: Option<f64>,
    /// Polynomial model orders P,Q (x^i x'^j, i <= P, j <= Q), e.g. 3,1.
    #[arg(long, value_parser = parse_order)]
    pub poly_order: Option<(u32, u32)>,
    /// Rig constants in a ROS 2 params YAML (`/**: ros__parameters: {mass_kg: 36.0}`).
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// A channel map (YAML): which column of a text, MDF4, TDMS, MAT or JSON file (channel:, with
    /// its unit or scale) or which topic and field of a bag recorded with the bench's own
    /// message types (topic:, field:) supplies each channel (see docs/data.md).
    #[arg(long, value_name = "MAP")]
    pub channels: Option<PathBuf>,
    /// Highest harmonic to analyse (default: as many as the sampling allows, at most 100;
    /// harmonics that do not stand out of their noise are dropped by the improved method).
    #[arg(long)]
    pub max_harmonic: Option<usize>,
    /// A sine step's labelled frequency stands within this relative difference of the
    /// frequency its driven channel shows, and within 5 standard deviations of that estimate;
    /// beyond both, the step is analysed at the estimate (with a warning naming both).
    #[arg(long, value_name = "REL", default_value_t = DEFAULT_FREQUENCY_TOLERANCE)]
    pub frequency_tolerance: f64,
    /// Held-out element-test records (a CSV export or a bag of the same setup; repeatable):
    /// the identified force law, and the moving mass times the acceleration, predicted along
    /// each record's measured motion; prints each record's force NMSE [%] and RMS error [N].
    #[arg(long, value_name = "FILE")]
    pub validate: Vec<PathBuf>,
    /// What an element test's bench controlled, for records of any excitation (no steps),
    /// whose samples cannot tell: force (a shaker driving a mass; its displacement is simulated
    /// under the measured force) or displacement (a dyno's stroke; the force is predicted along
    /// it). Default: the channel a labelled multisine's distortion shows, else displacement.
    #[arg(long, value_enum)]
    pub drive: Option<DriveArg>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Write SVG plots here: the force-state map of the fit and the validation time traces.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// What an element test's bench controlled (`--drive`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DriveArg {
    Force,
    Displacement,
}

impl From<DriveArg> for forcemap_math::sim::element::ElementDrive {
    fn from(d: DriveArg) -> Self {
        match d {
            DriveArg::Force => Self::Force,
            DriveArg::Displacement => Self::Displacement,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SystemArg {
    /// The 36 kg base-excited suspension rig (METHOD.md section 4).
    Rig,
    /// The 3-DOF example (METHOD.md section 3).
    ThreeDof,
    /// A twin-tube damper on a displacement-driven dyno (element test; docs/method.md):
    /// preload, gas spring, rebound/compression damping, seal friction, 0.8 kg fixture.
    DamperDyno,
    /// A 2 kg single-DOF system with cubic stiffness on a shaker (force-driven element test);
    /// its bag carries no mass_kg, so the mass is identified.
    ShakerSdof,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum CaseArg {
    I,
    Ii,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ExcitationArg {
    /// The system's stepped-sine program (with the rig's random validation records).
    Stepped,
    /// Periodic multisines (random-odd lines), then a band-random validation record.
    Multisine,
    /// One sine sweep over the stepped sine's band and time (rig, damper-dyno, shaker-sdof; the
    /// law by --sweep-kind), then (rig, unless --no-random) the two band-random validation
    /// records.
    Sweep,
    /// Rig: one band-random record over the stepped sine's band and time as the identification
    /// record (identified in the time domain: `forcemap identify --method td-all`).
    Random,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SweepKindArg {
    /// f(t) = f0 + (f1 - f0) t / T.
    Linear,
    /// f(t) = f0 (f1 / f0)^(t / T): equal time per octave.
    Log,
}

#[derive(Debug, Args)]
pub struct SimulateArgs {
    #[arg(long, value_enum, default_value_t = SystemArg::Rig)]
    pub system: SystemArg,
    /// 3-DOF force amplitudes: CASE I (5..25 N) or CASE II (50..90 N).
    #[arg(long, value_enum, default_value_t = CaseArg::Ii)]
    pub case: CaseArg,
    /// Measurement SNR [dB]; noise-free when absent.
    #[arg(long)]
    pub snr_db: Option<f64>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The drive: stepped sines; (shaker-sdof only) two periodic multisines and a band-random
    /// validation record; (rig, damper-dyno, shaker-sdof) one sine sweep; (rig) one band-random
    /// record.
    #[arg(long, value_enum, default_value_t = ExcitationArg::Stepped)]
    pub excitation: ExcitationArg,
    /// The law of --excitation sweep.
    #[arg(long, value_enum, default_value_t = SweepKindArg::Linear)]
    pub sweep_kind: SweepKindArg,
    /// Rig: skip the two band-random validation records.
    #[arg(long)]
    pub no_random: bool,
    #[command(flatten)]
    pub effects: EffectArgs,
    /// Write a test-bench CSV export here.
    #[arg(long, required_unless_present = "bag")]
    pub csv: Option<PathBuf>,
    /// Write a rosbag2 bag (MCAP) here: /rig/samples, /rig/excitation, /rig/parameters.
    #[arg(long)]
    pub bag: Option<PathBuf>,
}

/// Effects planted in the truth model (the "real rig" a simpler model may miss).
#[derive(Debug, Args, Default)]
pub struct EffectArgs {
    /// Cubic stiffness S of the element [N/m^3] (force S x^3).
    #[arg(long)]
    pub cubic_stiffness_n_per_m3: Option<f64>,
    /// Asymmetric (quadratic) stiffness [N/m^2] (force k2 x|x|).
    #[arg(long)]
    pub quadratic_stiffness_n_per_m2: Option<f64>,
    /// Quadratic damping [N s^2/m^2] (force c2 x'|x'|).
    #[arg(long)]
    pub quadratic_damping_n_s2_per_m2: Option<f64>,
    /// Stribeck friction: breakaway force [N] above the Coulomb level at low speed.
    #[arg(long)]
    pub stribeck_breakaway_n: Option<f64>,
    /// Stribeck velocity [m/s] of the decay from breakaway to the Coulomb level.
    #[arg(long, default_value_t = 0.01)]
    pub stribeck_velocity_mps: f64,
    /// Rig only: the element sees the base motion this much later than it is measured [s].
    #[arg(long)]
    pub exciter_delay_s: Option<f64>,
    /// Rig only: first-order low-pass of this cutoff [Hz] on every measured channel.
    #[arg(long)]
    pub sensor_lowpass_hz: Option<f64>,
    /// Rig only: the true mass is the nominal 36 kg times this factor.
    #[arg(long)]
    pub mass_factor: Option<f64>,
    /// Asymmetric damping: extra damping [N s/m] in rebound (relative velocity > 0), added to
    /// the element's; negative down to minus the element's damping.
    #[arg(long, allow_negative_numbers = true)]
    pub rebound_damping_n_s_per_m: Option<f64>,
    /// Asymmetric damping: extra damping [N s/m] in compression (relative velocity < 0).
    #[arg(long, allow_negative_numbers = true)]
    pub compression_damping_n_s_per_m: Option<f64>,
    /// Free-play: total width [m] of the gap (|x| <= gap/2) where the free-play spring is slack.
    #[arg(long, allow_negative_numbers = true)]
    pub free_play_gap_m: Option<f64>,
    /// Free-play: stiffness [N/m] of the spring outside the gap, force k (x - sgn(x) gap/2).
    #[arg(long, allow_negative_numbers = true)]
    pub free_play_stiffness_n_per_m: Option<f64>,
    /// Bouc-Wen hysteresis: force alpha z [N/m], z' = a x' - beta |x'| |z|^(n-1) z - gamma x' |z|^n.
    #[arg(long, allow_negative_numbers = true)]
    pub bouc_wen_alpha_n_per_m: Option<f64>,
    /// Bouc-Wen: a (dimensionless; default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub bouc_wen_a: Option<f64>,
    /// Bouc-Wen: beta [1/m^n].
    #[arg(long, allow_negative_numbers = true)]
    pub bouc_wen_beta_per_m_pow_n: Option<f64>,
    /// Bouc-Wen: gamma [1/m^n].
    #[arg(long, allow_negative_numbers = true)]
    pub bouc_wen_gamma_per_m_pow_n: Option<f64>,
    /// Bouc-Wen: exponent n (dimensionless; default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub bouc_wen_n: Option<f64>,
}

#[derive(Debug, Args)]
pub struct ImportArgs {
    #[command(subcommand)]
    pub command: ImportCommand,
}

#[derive(Debug, Subcommand)]
pub enum ImportCommand {
    /// Turn a test-bench CSV export into a bag, with the rig constants from flags or a params file.
    Csv {
        file: PathBuf,
        /// The bag directory to write (must not exist).
        #[arg(long)]
        out: PathBuf,
        /// Mass of the rig [kg], stored in the bag's /rig/parameters.
        #[arg(long)]
        mass_kg: Option<f64>,
        /// ROS 2 params YAML with the rig constants (mass_kg).
        #[arg(long)]
        params: Option<PathBuf>,
    },
    /// Turn an EMPS benchmark file (MATLAB v5 .mat: t, qm, qg, vir, gtau, kp, kv) into a bag:
    /// /emps/axis (forcemap_msgs/msg/AxisSample) and /emps/parameters (the gains).
    Emps {
        file: PathBuf,
        /// The bag directory to write (must not exist).
        #[arg(long)]
        out: PathBuf,
    },
}

fn parse_order(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not two whole numbers P,Q (e.g. 3,1)");
    let (p, q) = s.split_once(',').ok_or_else(bad)?;
    Ok((
        p.trim().parse().map_err(|_| bad())?,
        q.trim().parse().map_err(|_| bad())?,
    ))
}

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// A bag directory, a bare .mcap or a test-bench CSV export (sine steps and, for an element
    /// test, multisine records are fitted, random records held out); or an EMPS .mat file
    /// (time-domain path, scored on --validate).
    #[arg(required_unless_present = "demo", value_name = "DATA")]
    pub data: Vec<PathBuf>,
    /// The baseline model (see `forcemap models`; for EMPS: emps-viscous or emps-coulomb).
    #[arg(long, required_unless_present = "demo")]
    pub model: Option<String>,
    /// More held-out data (same forms as DATA): the rig's records simulated on the rig; an
    /// element test's sweep or band-random records, its force predicted from the measured
    /// motion.
    #[arg(long, num_args = 1.., value_name = "FILE")]
    pub validate: Vec<PathBuf>,
    /// Sine steps to hold out as well, e.g. 3,7.
    #[arg(long, value_delimiter = ',')]
    pub holdout_steps: Vec<usize>,
    /// Mass of the rig [kg] (overrides the params file and the bag).
    #[arg(long)]
    pub mass_kg: Option<f64>,
    /// Rig constants in a ROS 2 params YAML.
    #[arg(long)]
    pub params: Option<PathBuf>,
    /// A channel map (YAML) that DATA and --validate are read through: file columns
    /// (channel:) or a bag's topics (topic:, field:), see docs/data.md.
    #[arg(long, value_name = "MAP")]
    pub channels: Option<PathBuf>,
    /// Slope M [s/m] of the atan friction term (coulomb-atan baselines).
    #[arg(long)]
    pub atan_m: Option<f64>,
    /// A sine step's labelled frequency stands within this relative difference of the
    /// frequency its driven channel shows (see `forcemap identify --frequency-tolerance`).
    #[arg(long, value_name = "REL", default_value_t = DEFAULT_FREQUENCY_TOLERANCE)]
    pub frequency_tolerance: f64,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// Write an HTML report with SVG plots into this new directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// The built-in demo: the linear "sim" against simulated rig data with Coulomb friction.
    #[arg(long, conflicts_with_all = ["data", "validate"])]
    pub demo: bool,
    /// What an element test's bench controlled, for records with no steps (as identify's
    /// --drive): with force, the baseline and the named effect are also refitted by output
    /// error (the mass simulated under each record's measured force) and the held-out records'
    /// displacement simulated.
    #[arg(long, value_enum)]
    pub drive: Option<DriveArg>,
}

#[derive(Debug, Args)]
pub struct DiagnoseEvalArgs {
    /// Number of generated cases.
    #[arg(long, default_value_t = 40)]
    pub cases: usize,
    /// Seeds of the case generator: `--seed 1,2,3` runs `--cases` of each and reports every
    /// figure pooled over them, with each seed's own beside it.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub seed: Vec<u64>,
    /// The lower measurement SNR [dB]; half of the cases are 10 dB cleaner.
    #[arg(long, default_value_t = 30.0)]
    pub snr_db: f64,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// Run only these case indices (of the `--cases` generated from `--seed`), to look at one
    /// case again: `--only 12,45`.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<usize>,
    /// One JSON object (summary and cases) instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Also write that JSON object to this file (whole or not at all) while the tables print:
    /// one run for both.
    #[arg(long, value_name = "PATH")]
    pub json_file: Option<std::path::PathBuf>,
    /// The forms of the planted effects: `exact` plants each in its candidate's form; `wide`
    /// draws each from a wider family in a world simulator of its own, adds new-name and
    /// out-of-library effects, and reports each group separately (its SNRs are fixed, 20, 30
    /// and 40 dB: `--snr-db` is not used).
    #[arg(long, value_enum, default_value_t = EvalForms::Exact)]
    pub forms: EvalForms,
}

/// The forms `diagnose-eval` plants its effects in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EvalForms {
    Exact,
    Wide,
}
