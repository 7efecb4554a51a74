//! The runner: runs checks against a renderer, applies the family-wise correction across the
//! stochastic ones, and turns measurements into verdicts with their numbers.

use super::budget;
use super::context::{check_seed, Context, Correction, RunOptions};
use super::isolation;
use super::kind::Check;
pub use super::measurement::judge;
use super::measurement::Measurement;
use super::model::local::LocalModels;
use super::outcome::{Outcome, RunReport, ShardInfo, Statistic, Verdict};
use super::renderer::Renderer;
use super::shared::SharedRenders;
use super::under_test::{Filtered, ModelSource, Subject};
use crate::stats::{multiple, power};
use std::time::Instant;

/// What the runner reports while it runs.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// A check starts.
    Started(&'a str),
    /// A check ended, with its verdict (final under Šidák; under Holm's step-down the
    /// verdicts of stochastic checks are settled only when all have run, and this is the
    /// outcome before them).
    Finished(&'a Outcome),
    /// The isolation ladder of this failed check starts (after every check has run).
    Isolating(&'a str),
}

/// Sets `o`'s threshold, detection power and verdict from its measurement, given whether
/// the correction rejected its p-value at `threshold`.
fn settle(o: &mut Outcome, ms: &Measurement, test: Option<(bool, f64)>) {
    let mut pass = ms.deterministic_pass.unwrap_or(true);
    if let Some((rejected, threshold)) = test {
        o.alpha = Some(threshold);
        pass &= !rejected;
    }
    // Detection power at the level this test actually ran at: the corrected threshold,
    // split over the sub-tests folded into the p-value, one- or two-sided, plus the
    // stated model tolerance.
    let se = ms.power_std_error.or(ms.std_error);
    let scale = ms.power_scale.or(ms.expected.map(f64::abs));
    if let (Some((dof, draws)), Some(thr)) = (ms.power_chi_square, o.alpha) {
        let w = power::chi_square_min_detectable_w(dof, draws, ms.sub_test_level(thr), 0.95);
        o.detection_power = w.is_finite().then_some(w);
    } else if let (Some(se), Some(scale), Some(thr)) = (se, scale, o.alpha) {
        if scale != 0.0 {
            let level = ms.sub_test_level(thr);
            o.detection_power =
                Some(o.rel_tolerance + power::min_detectable_bias(se, level, 0.95) / scale);
        }
    }
    let rejected = test.is_some_and(|t| t.0);
    o.verdict = if ms.unstable.is_some() && !(ms.retested && rejected) {
        if !o.message.starts_with(ms.unstable.as_deref().unwrap_or("")) {
            o.message = format!("{}; {}", ms.unstable.as_deref().unwrap_or(""), o.message);
        }
        Verdict::Unstable
    } else if let (true, true, Some(heavy)) = (
        rejected,
        ms.deterministic_pass.unwrap_or(true),
        ms.heavy_tail.as_deref(),
    ) {
        // the rejection rests on a tail the mean test cannot allow for
        o.message = format!("{heavy}; {}", o.message);
        Verdict::Unstable
    } else if pass {
        Verdict::Pass
    } else {
        Verdict::Fail
    };
}

/// Runs `checks` against `renderer` and, for furnace's own renderer, its models in process;
/// `progress` sees each check start and end.
pub fn run(
    checks: &[Check],
    opts: &RunOptions,
    renderer: &dyn Renderer,
    manifests: Vec<String>,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> RunReport {
    let local = LocalModels;
    let models: Option<&dyn ModelSource> = renderer.is_reference().then_some(&local as _);
    run_with(
        checks,
        opts,
        Subject { renderer, models },
        manifests,
        progress,
    )
}

/// Runs `checks` against `subject` (a renderer and the models it serves).
pub fn run_with(
    checks: &[Check],
    opts: &RunOptions,
    subject: Subject,
    manifests: Vec<String>,
    progress: &mut (dyn FnMut(Progress) + Send),
) -> RunReport {
    let renderer = subject.renderer;
    let start = Instant::now();
    let m = checks
        .iter()
        .filter(|c| c.kind.stochastic())
        .filter(|c| c.kind.not_applicable(c, &subject).is_none())
        .count()
        .max(1);
    let alpha = multiple::sidak_alpha(opts.family_alpha, m);
    let level = RunLevel {
        alpha,
        plan: budget::Plan::new(alpha, opts.power, opts.sequential),
        shared: SharedRenders::new(opts.seed),
    };
    let todo: Vec<&Check> = checks
        .iter()
        .enumerate()
        .filter(|(i, _)| {
            opts.shard
                .as_ref()
                .is_none_or(|plan| plan.of_check.get(*i) == Some(&plan.shard.index))
        })
        .map(|(_, c)| c)
        .collect();
    let progress = std::sync::Mutex::new(progress);
    let report = |event: Progress| {
        let mut p = progress.lock().unwrap_or_else(|e| e.into_inner());
        (*p)(event)
    };
    let one =
        |check: &Check, threads: usize| run_one(check, opts, threads, &subject, &level, &report);
    let done: Vec<(Outcome, Option<Measurement>)> = match concurrent_checks(opts, &subject) {
        1 => todo.iter().map(|c| one(c, opts.threads)).collect(),
        n => side_by_side(&todo, n, &one),
    };
    let progress = progress.into_inner().unwrap_or_else(|e| e.into_inner());
    let (mut outcomes, measured): (Vec<Outcome>, Vec<Option<Measurement>>) =
        done.into_iter().unzip();
    // Verdicts: the deterministic part, then the stochastic part under the correction.
    let p_values: Vec<(usize, f64)> = measured
        .iter()
        .enumerate()
        .filter_map(|(i, ms)| ms.as_ref().and_then(|m| m.p_value.map(|p| (i, p))))
        .collect();
    let holm = match opts.correction {
        Correction::Holm => Some(multiple::holm(
            &p_values.iter().map(|x| x.1).collect::<Vec<_>>(),
            opts.family_alpha,
        )),
        Correction::Sidak => None,
    };
    if let Some(h) = &holm {
        for (i, ms) in measured.iter().enumerate() {
            let Some(ms) = ms else { continue };
            let test = ms.p_value.map(|p| {
                let k = p_values.iter().position(|x| x.0 == i).unwrap_or(0);
                h.get(k).copied().unwrap_or((p <= alpha, alpha))
            });
            settle(&mut outcomes[i], ms, test);
        }
    }
    if opts.isolate {
        isolate_failures(checks, &mut outcomes, opts, &subject, alpha, progress);
    }
    RunReport {
        furnace_version: env!("CARGO_PKG_VERSION").to_string(),
        renderer: renderer.name(),
        manifests,
        seed: opts.seed,
        family_alpha: opts.family_alpha,
        correction: opts.correction.name().into(),
        stochastic_tests: m,
        looks: if opts.sequential {
            "sequential"
        } else {
            "fixed"
        }
        .into(),
        power: opts.power,
        outcomes,
        seconds: start.elapsed().as_secs_f64(),
        machine: crate::harness::machine::description(),
        shard: opts.shard.as_ref().map(|p| ShardInfo {
            index: p.shard.index,
            count: p.shard.count,
            suite: checks
                .iter()
                .map(|c| c.name.clone())
                .chain(p.also.iter().cloned())
                .collect(),
        }),
    }
}

/// What the checks of one run share: the per-test level, the sample plan and the reference
/// renders.
struct RunLevel {
    alpha: f64,
    plan: Result<budget::Plan, String>,
    shared: SharedRenders,
}

/// How many checks run side by side: one per core for furnace's own renderer on every core
/// (`threads` 0); one at a time otherwise (an external renderer keeps one check's files apart
/// from the next; `-j N` asks for N threads).
fn concurrent_checks(opts: &RunOptions, subject: &Subject) -> usize {
    if opts.threads != 0 || !subject.renderer.is_reference() {
        return 1;
    }
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Runs `todo` on `n` threads that each take the next check not yet started; the outcomes
/// come back in `todo`'s order. A check renders on one thread of its own while other checks
/// wait to start, so each core runs one check without waiting on a shared pool (where short
/// parallel renders queued behind long ones: docs/performance.md); the checks left when the
/// queue empties render on every core (`threads` 0). A check's numbers depend only on its
/// seed (and the run's, for shared references), so they are those of a run one check at a
/// time.
fn side_by_side<T: Send>(
    todo: &[&Check],
    n: usize,
    one: &(dyn Fn(&Check, usize) -> T + Sync),
) -> Vec<T> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let slots: Vec<std::sync::Mutex<Option<T>>> =
        todo.iter().map(|_| std::sync::Mutex::new(None)).collect();
    std::thread::scope(|scope| {
        for _ in 0..n.min(todo.len()) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(check) = todo.get(i) else { break };
                let waiting = todo.len() - i - 1;
                let r = one(check, if waiting >= n - 1 { 1 } else { 0 });
                *slots[i].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
            });
        }
    });
    slots
        .into_iter()
        .map(|s| {
            s.into_inner()
                .unwrap_or_else(|e| e.into_inner())
                .expect("every check ran")
        })
        .collect()
}

/// Runs one check on `threads` render threads (0: every core): its applicability, its
/// measurement under the sample plan, and, under Šidák, its verdict (Holm's waits for every
/// p-value).
fn run_one(
    check: &Check,
    opts: &RunOptions,
    threads: usize,
    subject: &Subject,
    level: &RunLevel,
    progress: &(dyn Fn(Progress) + Sync),
) -> (Outcome, Option<Measurement>) {
    let RunLevel {
        alpha,
        plan,
        shared,
    } = level;
    let alpha = *alpha;
    let renderer = subject.renderer;
    progress(Progress::Started(&check.name));
    if let Some(why) = check.kind.not_applicable(check, subject) {
        let mut o = Outcome::new(&check.name, check.kind_name());
        o.verdict = Verdict::Skipped;
        o.message = why;
        progress(Progress::Finished(&o));
        return (o, None);
    }
    let filtered = subject.models.map(|inner| Filtered {
        inner,
        globs: &check.models,
    });
    let limit = check.time_limit.unwrap_or(opts.time_limit);
    let ctx = Context {
        deadline: Some(Instant::now() + std::time::Duration::from_secs_f64(limit)),
        renderer,
        models: match &filtered {
            Some(f) if !check.models.is_empty() => Some(f as &dyn ModelSource),
            _ => subject.models,
        },
        seed: check_seed(check.seed, &check.name, opts.seed),
        threads,
        alpha,
        // a check with its own seed renders its references with it
        shared: check.seed.is_none().then_some(shared),
        looks: plan.as_ref().is_ok_and(|p| p.designs.is_some()),
    };
    let t0 = Instant::now();
    let result = match plan {
        Ok(plan) => budget::run(check, &ctx, plan),
        Err(why) => Err(super::error::CheckError::Setup(why.clone())),
    };
    let seconds = t0.elapsed().as_secs_f64();
    let mut o = Outcome::new(&check.name, check.kind_name());
    o.seconds = seconds;
    o.rel_tolerance = check.rel_tolerance;
    o.regression = check.regression;
    let measured = match result {
        Err(super::error::CheckError::Unsupported(why)) => {
            o.verdict = Verdict::Skipped;
            o.message = format!(
                "{} cannot express this check's scene: {why}",
                renderer.name()
            );
            None
        }
        Err(e) => {
            o.verdict = Verdict::Error;
            o.message = format!("{e} ({})", check.origin);
            None
        }
        Ok(ms) => {
            o.estimate = ms.estimate;
            o.std_error = ms.std_error;
            o.expected = ms.expected;
            o.statistic = ms.statistic.clone().unwrap_or(Statistic::None);
            o.p_value = ms.p_value;
            o.samples = ms.samples;
            o.message = ms.message.clone();
            // what the test allowed: the stated tolerance and a black box's rounding
            o.rel_tolerance = ms.rel_tolerance.unwrap_or(check.rel_tolerance);
            o.regression |= ms.regression;
            let finite = [ms.estimate, ms.std_error, ms.p_value]
                .iter()
                .flatten()
                .all(|v| v.is_finite());
            if !finite {
                o.verdict = Verdict::Error;
                o.message = format!(
                    "non-finite estimate, standard error or p-value; {}",
                    o.message
                );
                None
            } else if ms.samples == 0
                && !renderer.is_reference()
                && !check.models.is_empty()
                && names_furnace_models(&check.models)
            {
                // another renderer that serves no model of this kind among those the check
                // names is not judged by it; for furnace, or globs naming none of furnace's
                // models (a typo), measuring nothing stays an ERROR below
                o.verdict = Verdict::Skipped;
                o.message = format!(
                    "{} serves no model this check can measure among those its `models` {:?} name (nothing was measured)",
                    renderer.name(),
                    check.models
                );
                None
            } else if ms.samples == 0 {
                // a check that measured nothing (every model left out by its declared flags,
                // say) cannot pass
                o.verdict = Verdict::Error;
                o.message = format!(
                    "nothing was measured (0 samples), so nothing can pass; {}",
                    o.message
                );
                None
            } else {
                if let (Correction::Sidak, p) = (opts.correction, ms.p_value) {
                    settle(&mut o, &ms, p.map(|p| (p <= alpha, alpha)));
                }
                Some(ms)
            }
        }
    };
    progress(Progress::Finished(&o));
    (o, measured)
}

/// Runs the isolation ladder of every failed or unstable check, each within
/// [`isolation::BUDGET_FACTOR`] times the check's own time.
fn isolate_failures(
    checks: &[Check],
    outcomes: &mut [Outcome],
    opts: &RunOptions,
    subject: &Subject,
    alpha: f64,
    progress: &mut (dyn FnMut(Progress) + Send),
) {
    for o in outcomes.iter_mut() {
        if !matches!(o.verdict, Verdict::Fail | Verdict::Unstable) {
            continue;
        }
        let Some(check) = checks.iter().find(|c| c.name == o.name) else {
            continue;
        };
        let ctx = Context {
            renderer: subject.renderer,
            models: subject.models,
            seed: check_seed(check.seed, &check.name, opts.seed),
            threads: opts.threads,
            // the level the check itself was judged at (Holm's step-down threshold included)
            alpha: o.alpha.unwrap_or(alpha),
            deadline: None,
            shared: None,
            looks: false,
        };
        let ladder = check.kind.ladder(check);
        if ladder.is_empty() {
            continue;
        }
        progress(Progress::Isolating(&check.name));
        let budget = isolation::BUDGET_FACTOR * o.seconds.max(0.1);
        let deviation = o
            .estimate
            .zip(o.expected)
            .and_then(|(e, x)| isolation::relative(e, x));
        o.isolation = isolation::isolate(&ladder, &ctx, opts.seed, budget, deviation);
    }
}

/// Whether `globs` name one of furnace's own models (a manifest written for furnace's names;
/// globs that name none are a typo).
fn names_furnace_models(globs: &[String]) -> bool {
    let ours = Filtered {
        inner: &LocalModels,
        globs,
    };
    [
        ours.bsdfs().map_or(0, |m| m.len()),
        ours.phases().map_or(0, |m| m.len()),
        ours.emitters().map_or(0, |m| m.len()),
    ]
    .iter()
    .any(|&n| n > 0)
}
