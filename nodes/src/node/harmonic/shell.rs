//! The harmonic node's ROS shell: its parameters, subscriptions and publishers around
//! [`HarmonicState`], and the analysis worker that publishes each step's phasors.

use super::*;

/// How long after its phasors are published a step's stream and record are freed.
const FREE_AFTER: Duration = Duration::from_millis(100);

/// Frees `spent` [`FREE_AFTER`] from now, off the path from a step's last sample to theta:
/// releasing a 10 kHz step's megabytes took up to ~1 ms of CPU and, freed at once after the
/// publish, delayed the phasors' sending by about as much (`forcemap bench graph --trace`,
/// docs/graph.md); theta follows its last sample by a few ms.
fn free_later<T: Send + 'static>(spent: T) {
    tokio::spawn(async move {
        tokio::time::sleep(FREE_AFTER).await;
        drop(spent);
    });
}

pub async fn run(setup: NodeSetup) -> anyhow::Result<()> {
    let p = &setup.params;
    let mut options = PhasorOptions {
        max_harmonic: p
            .opt_usize("max_harmonic")?
            .unwrap_or(IDENTIFICATION_MAX_HARMONIC),
        ..PhasorOptions::for_identification()
    };
    if let Some(m) = p.opt_usize("min_periods")? {
        options.min_periods = m;
    }
    let find_steps = p.opt_bool("find_steps")?.unwrap_or(false);
    let frequency_tolerance = p
        .opt_f64("frequency_tolerance")?
        .unwrap_or(DEFAULT_FREQUENCY_TOLERANCE);
    let update_period_s = p.opt_f64("update_period_s")?;
    let run_end_silence_s = p.opt_f64("run_end_silence_s")?;
    let frame = p.opt_str("frame_id")?.unwrap_or("rig").to_string();
    let fq = setup.fully_qualified_name();

    let mut ros = RosNode::start(setup.clone())?;
    let samples = ros.subscription::<RigSample>(topics::SAMPLES, qos::samples_reader())?;
    let excitation = ros.subscription::<ExcitationState>(topics::EXCITATION, qos::excitation())?;
    let phasors_pub = ros.publisher::<HarmonicPhasors>(topics::PHASORS, qos::phasors())?;
    let diag_pub = ros.publisher::<DiagnosticArray>(topics::DIAGNOSTICS, qos::diagnostics())?;
    // Only a node giving provisional phasors has their writer (the graph is otherwise as before).
    let provisional_pub = match update_period_s {
        Some(_) => {
            Some(ros.publisher::<HarmonicPhasors>(topics::PROVISIONAL_PHASORS, qos::phasors())?)
        }
        None => None,
    };

    let (tx, mut rx) = mpsc::unbounded_channel::<Input>();
    forward(
        samples,
        tx.clone(),
        OnTakeError::Warn("a sample"),
        |m, _| Some(Input::Sample(m)),
    );
    forward(
        excitation,
        tx.clone(),
        OnTakeError::Warn("an excitation state"),
        |m, _| Some(Input::Excitation(m)),
    );
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(200));
        loop {
            tick.tick().await;
            if tx.send(Input::Tick).is_err() {
                break;
            }
        }
    });

    // Analysis runs on its own task, in step order, so sample intake never waits for it.
    let (atx, mut arx) = mpsc::unbounded_channel::<(Outcome, Option<Record>)>();
    let status_name = format!("{fq}: harmonic analysis");
    let diag_pub = std::sync::Arc::new(diag_pub);
    let diag_for_worker = diag_pub.clone();
    let frame_w = frame.clone();
    let status_w = status_name.clone();
    let options_w = options.clone();
    let worker = tokio::spawn(async move {
        let options = options_w;
        let mut analysed = 0usize;
        // `spent`: the step's record, freed with its analysis after the phasors are out.
        while let Some((job, spent)) = arx.recv().await {
            let (mut analysis, origin) = match job {
                Outcome::Analyse(analysis, origin) => (analysis, origin),
                Outcome::Provisional(stream, origin) => {
                    if let Some(p) = &provisional_pub {
                        provisional::publish(stream, origin, p, &frame_w).await;
                    }
                    continue;
                }
                Outcome::Skipped(..) | Outcome::Dropped(_) | Outcome::Warning(_) => continue,
            };
            let step = analysis.step();
            let multisine = analysis.is_multisine();
            let how = if analysis.is_streamed() {
                ""
            } else if multisine {
                " (multisine: its averaged period's bins)"
            } else {
                " (batch: the record's sample rate was not the stream's)"
            };
            let trace_step = step as u32;
            latency_trace::mark_now("harmonic.analysis_start", trace_step, None);
            let analysis_ahead = analysis.analysed_ahead();
            let opts = options.clone();
            let run = move || {
                let (an, cpu_ns) = latency_trace::cpu_of(|| analysis.analyse(&opts));
                latency_trace::mark_now("harmonic.analysis_done", trace_step, cpu_ns);
                (an, analysis)
            };
            // A stream analysed ahead only hands its analysis over: no thread hop for that.
            let result = if analysis_ahead {
                Ok(run())
            } else {
                tokio::task::spawn_blocking(run).await
            };
            match result {
                Ok((Ok(an), analysis)) => {
                    analysed += 1;
                    let (mut msg, cpu_ns) = latency_trace::cpu_of(|| {
                        HarmonicPhasors::from_analysis(
                            &an,
                            origin,
                            Header::new(now_time(), &frame_w),
                        )
                    });
                    latency_trace::mark_now("harmonic.message_built", trace_step, cpu_ns);
                    if multisine {
                        msg.harmonic_cap = HarmonicPhasors::MULTISINE_CAP;
                    }
                    if let Err(e) = phasors_pub.async_publish(msg).await {
                        log_line!("error: publishing the phasors of step {step}: {e:?}");
                    }
                    latency_trace::mark_now("harmonic.phasors_published", trace_step, None);
                    // Said once the phasors are out: the log's write is not on their path.
                    log_line!(
                        "step {step}: {:.3} Hz, {} settled periods{} -> phasors of {} harmonics{how}",
                        an.frequency_hz,
                        an.periods_used,
                        if an.settled { "" } else { " (NOT settled)" },
                        an.harmonics
                    );
                    latency_trace::flush();
                    free_later((analysis, spent));
                    let status = DiagnosticStatus::new(
                        if an.settled {
                            DiagnosticStatus::OK
                        } else {
                            DiagnosticStatus::WARN
                        },
                        &status_w,
                        format!("step {step} analysed"),
                        "harmonic",
                    )
                    .with_value("steps_analysed", analysed)
                    .with_value("last_step", step);
                    let _ = diag_for_worker
                        .async_publish(DiagnosticArray {
                            header: Header::new(now_time(), ""),
                            status: vec![status],
                        })
                        .await;
                }
                Ok((Err(e), _)) => {
                    log_line!("step {step}: dropped: phasor analysis failed: {e}");
                }
                Err(e) => log_line!("step {step}: analysis task failed: {e}"),
            }
        }
    });

    let mut state = HarmonicState::with_options(options.clone())
        .with_frequency_tolerance(frequency_tolerance)?;
    if let Some(t) = update_period_s {
        state = state.with_updates(t)?;
        log_line!("provisional phasors of a step in progress every {t} s of its samples");
    }
    if let Some(s) = run_end_silence_s {
        state = state.with_run_end_silence(s)?;
    }
    if find_steps {
        state = state.finding_steps()?;
        log_line!("finding the steps in the samples (find_steps): excitation states are ignored");
    }
    let mut dropped = 0usize;
    log_line!(
        "waiting for samples on {} (max_harmonic {})",
        setup.absolute_topic(topics::SAMPLES),
        options.max_harmonic
    );
    loop {
        let input = tokio::select! {
            i = rx.recv() => match i { Some(i) => i, None => break },
            () = crate::ros::shutdown_signal() => break,
        };
        // Traced: when the input arrived (for a step's last sample) and the CPU its handling took.
        let traced = latency_trace::enabled()
            .then(|| (latency_trace::wall_ns(), latency_trace::thread_cpu_ns()));
        for out in state.handle(input, Instant::now()) {
            match out {
                job @ (Outcome::Analyse(..) | Outcome::Provisional(..)) => {
                    if let (Some((arrived_ns, cpu0)), Outcome::Analyse(analysis, _)) =
                        (traced, &job)
                    {
                        let step = analysis.step() as u32;
                        latency_trace::mark("harmonic.sample_in", step, arrived_ns, None);
                        let cpu_ns = latency_trace::thread_cpu_ns() - cpu0;
                        latency_trace::mark_now("harmonic.step_complete", step, Some(cpu_ns));
                    }
                    let _ = atx.send((job, state.take_spent()));
                }
                Outcome::Skipped(step, why) => log_line!("step {step}: {why}"),
                Outcome::Warning(w) => {
                    log_line!("warning: {w}");
                    let status =
                        DiagnosticStatus::new(DiagnosticStatus::WARN, &status_name, w, "harmonic");
                    let _ = diag_pub
                        .async_publish(DiagnosticArray {
                            header: Header::new(now_time(), ""),
                            status: vec![status],
                        })
                        .await;
                }
                Outcome::Dropped(e) => {
                    dropped += 1;
                    log_line!("step {}: DROPPED: {}", e.step, e.problem);
                    let status = DiagnosticStatus::new(
                        DiagnosticStatus::WARN,
                        &status_name,
                        format!("step {} dropped: {}", e.step, e.problem),
                        "harmonic",
                    )
                    .with_value("steps_dropped", dropped)
                    .with_value("dropped_step", e.step);
                    let _ = diag_pub
                        .async_publish(DiagnosticArray {
                            header: Header::new(now_time(), ""),
                            status: vec![status],
                        })
                        .await;
                }
            }
        }
    }
    drop(atx);
    let _ = tokio::time::timeout(Duration::from_secs(5), worker).await;
    Ok(())
}
