//! Hostile inputs (issue 18): the input formats besides URDF (tests/urdf_import.rs has its
//! own) mutated at random — truncated, bytes edited, numbers poisoned — must give a result or
//! an error that names the file, never a panic, and never take longer than a deadline.
//! Formats: a robot description (TOML), a task, a walk scenario, a jump (TOML), and a
//! trajectory (JSON).

use legwork::io::{Knot, Trajectory};
use legwork::model::{description, embedded};
use legwork::ocp::TaskSpec;
use legwork::terrain::{Plane, Terrain};
use proptest::prelude::*;

#[path = "support/number_spans.rs"]
mod number_spans;
use number_spans::number_spans;
use std::sync::mpsc;
use std::time::Duration;

/// Longer than any parse should take by orders of magnitude; a case past it is a hang.
const DEADLINE: Duration = Duration::from_secs(20);
const ORIGIN: &str = "hostile-input.file";

/// The formats: a name, a valid text, and what legwork does with such a file before any
/// long work starts (parse and validate), as text: `Ok` or the error's message.
#[derive(Clone, Copy, Debug)]
enum Format {
    Robot,
    Task,
    Scenario,
    Jump,
    Trajectory,
}

const FORMATS: [Format; 5] = [Format::Robot, Format::Task, Format::Scenario, Format::Jump, Format::Trajectory];

fn trajectory_text() -> &'static str {
    static TEXT: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TEXT.get_or_init(|| {
        let model = embedded::load("a1").unwrap();
        let ground = Plane::flat(0.0);
        let q = legwork::sim::standing_on_ground(&model, &ground, 0.0).unwrap();
        let mut traj = Trajectory::new(&model, "hostile", 0.01, ground.spec());
        for k in 0..3 {
            traj.knots.push(Knot {
                t: k as f64 * 0.01,
                q: q.iter().copied().collect(),
                v: vec![0.0; model.nv],
                tau: vec![1.5; model.nv - 6],
                contact_force: vec![[0.0, 0.0, 30.0]; 4],
                in_contact: vec![true; 4],
                feedback_gain: Some(vec![vec![0.5; 2 * model.nv]; model.nv - 6]),
            });
        }
        serde_json::to_string_pretty(&traj).unwrap()
    })
}

impl Format {
    fn source(self) -> &'static str {
        match self {
            Format::Robot => embedded::source("a1").unwrap(),
            Format::Task => legwork::ocp::EMBEDDED_TASKS.iter().find(|(n, _)| *n == "pallet_push").unwrap().1,
            Format::Scenario => legwork::walk::EMBEDDED_SCENARIOS[0].1,
            Format::Jump => legwork::jump::EMBEDDED_JUMPS.iter().find(|(n, _, _)| *n == "barrel_roll").unwrap().2,
            Format::Trajectory => trajectory_text(),
        }
    }

    /// What the command line does with the file before its work starts.
    fn read(self, text: &str) -> Result<(), String> {
        let e = |e: &dyn std::fmt::Display| e.to_string();
        match self {
            Format::Robot => description::from_str(text, ORIGIN).map(|_| ()).map_err(|x| e(&x)),
            Format::Task => {
                let spec = TaskSpec::from_toml(text, ORIGIN).map_err(|x| e(&x))?;
                let model = spec.load_robot(ORIGIN).map_err(|x| e(&x))?;
                spec.target(&model, ORIGIN).map_err(|x| e(&x))?;
                let _ = spec.estimated_memory_bytes();
                Ok(())
            }
            Format::Scenario => legwork::walk::ScenarioSpec::from_toml(text, ORIGIN).map(|_| ()).map_err(|x| e(&x)),
            Format::Jump => legwork::jump::Jump::from_toml(text, ORIGIN).map(|_| ()).map_err(|x| e(&x)),
            Format::Trajectory => {
                let traj = Trajectory::from_json(text, ORIGIN).map_err(|x| e(&x))?;
                traj.check_against(&embedded::load("a1").unwrap(), ORIGIN).map_err(|x| e(&x))
            }
        }
    }
}

/// Reads `text` as `format` on another thread: a panic or a hang past the deadline fails
/// the case; an error must name the file.
fn must_answer(format: Format, text: String) -> Result<(), TestCaseError> {
    let (send, receive) = mpsc::channel();
    let worker = std::thread::spawn(move || {
        let _ = send.send(format.read(&text));
    });
    match receive.recv_timeout(DEADLINE) {
        Ok(Ok(())) => {}
        Ok(Err(message)) => prop_assert!(message.contains(ORIGIN), "{format:?}: the error does not name the file: {message}"),
        Err(mpsc::RecvTimeoutError::Timeout) => prop_assert!(false, "{format:?}: no answer within {DEADLINE:?}"),
        Err(mpsc::RecvTimeoutError::Disconnected) => prop_assert!(false, "{format:?}: panicked"),
    }
    let _ = worker.join();
    Ok(())
}

const POISON: [&str; 10] = ["nan", "-1", "0", "inf", "-inf", "1e308", "-1e300", "1e9", "\"x\"", ""];

#[test]
fn every_format_reads_as_given() {
    for format in FORMATS {
        assert_eq!(format.read(format.source()), Ok(()), "{format:?}");
        assert!(number_spans(format.source()).len() > 5, "{format:?} has numbers to poison");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, .. ProptestConfig::default() })]

    #[test]
    fn truncated_files_give_a_named_answer(which in 0usize..FORMATS.len(), cut in any::<prop::sample::Index>()) {
        let format = FORMATS[which];
        let src = format.source();
        let cut = cut.index(src.len() + 1);
        let cut = (0..=cut).rev().find(|&c| src.is_char_boundary(c)).unwrap_or(0);
        must_answer(format, src[..cut].to_string())?;
    }

    #[test]
    fn edited_bytes_give_a_named_answer(which in 0usize..FORMATS.len(), edits in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8)) {
        let format = FORMATS[which];
        let mut bytes = format.source().as_bytes().to_vec();
        for (at, byte, op) in edits {
            if bytes.is_empty() {
                break;
            }
            let i = at.index(bytes.len());
            match op {
                0 => bytes[i] = byte,
                1 => {
                    bytes.remove(i);
                }
                _ => bytes.insert(i, byte),
            }
        }
        must_answer(format, String::from_utf8_lossy(&bytes).into_owned())?;
    }

    #[test]
    fn poisoned_numbers_give_a_named_answer(which in 0usize..FORMATS.len(), picks in prop::collection::vec((any::<prop::sample::Index>(), 0usize..POISON.len()), 1..4)) {
        let format = FORMATS[which];
        let mut text = format.source().to_string();
        for (at, p) in picks {
            let spans = number_spans(&text);
            if spans.is_empty() {
                break;
            }
            let (a, b) = spans[at.index(spans.len())];
            text.replace_range(a..b, POISON[p]);
        }
        must_answer(format, text)?;
    }
}
