//! Every event as a line of Foxglove's Log panel (`foxglove.Log` on `/events`): when, how
//! grave, the event in the words every reader shares ([`Teller`]: the live lines of `marie
//! run` and the monitor's timeline say the same), and the node that published it.
//!
//! The levels are the words' [`Gravity`]: ERROR for what ends or breaks a run, WARNING for
//! faults and what they cause, DEBUG for the high-rate telemetry (poses ten times a second,
//! echoes, datamanager acknowledgements) so that the panel's INFO filter shows the run's
//! story, INFO for the rest. A binding of several operations is one entry, its lines joined
//! by `; `.

use super::schemas::{Log, Time};
#[cfg(doc)]
use marie::events::Teller;
use marie::events::{Event, Gravity, Words};

/// `foxglove.LogLevel` DEBUG.
pub(crate) const DEBUG: u8 = 1;
/// INFO.
pub(crate) const INFO: u8 = 2;
/// WARNING.
pub(crate) const WARNING: u8 = 3;
/// ERROR.
pub(crate) const ERROR: u8 = 4;

/// `event` as a log line, in `words` (its [`Teller`]'s).
pub(crate) fn log(event: &Event, words: &Words) -> Log {
    Log {
        timestamp: Time::from_ms(event.at_ms),
        level: level(words.gravity),
        message: words.text.replace('\n', "; "),
        name: event.node.clone(),
        file: "",
        line: 0,
    }
}

/// Foxglove's level of `gravity`.
fn level(gravity: Gravity) -> u8 {
    match gravity {
        Gravity::Detail => DEBUG,
        Gravity::Info => INFO,
        Gravity::Warning => WARNING,
        Gravity::Error => ERROR,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use marie::events::Teller;

    /// The module docs' example line of each kind.
    const LINES: &str = r#"{"at_ms":1260,"node":"n","kind":{"type":"action_started","action":"follow","run_ms":60,"operations":[{"key":"wall-follower","name":"wall-follower","id":1512,"version":"1.0.0","node":"n","address":"0.41"}]}}
{"at_ms":9810,"node":"n","kind":{"type":"action_ended","action":"follow","run_ms":8610,"flags":["dock_found"],"status":4,"result":"failed"}}
{"at_ms":30000,"node":"n","kind":{"type":"run_ended","outcome":"failed","reason":"no dock","run_ms":28800,"status":12,"flags":[]}}
{"at_ms":5000,"node":"n","kind":{"type":"fault_injected","fault":"kill","operation":"wall-follower","actor":"0.41","node":"n","due_ms":3800}}
{"at_ms":4100,"node":"n","kind":{"type":"dm_acked","dm":"world","source":"wall-sensor","class":"wall","seq":212,"digest":1311768467463790320}}
{"at_ms":20,"node":"n","kind":{"type":"robot","what":"pose","data":{"heading":3.14,"x":12.5,"y":1.5}}}
{"at_ms":4000,"node":"n","kind":{"type":"robot","what":"collision","data":{"x":1.0,"y":2.0}}}"#;

    #[test]
    fn events_read_as_lines_at_their_level() {
        let mut teller = Teller::default().with_robot_words(marie_telemetry::words);
        let logs: Vec<Log> = LINES
            .lines()
            .map(|l| {
                let event = Event::from_json_line(l).unwrap();
                log(&event, &teller.tell(&event))
            })
            .collect();
        let got: Vec<(u8, &str)> = logs.iter().map(|l| (l.level, l.message.as_str())).collect();
        assert_eq!(
            got,
            [
                (INFO, "follow: start [wall-follower]"),
                (WARNING, "follow: failed, status 0x00000004 [dock_found]"),
                (ERROR, "run FAILED after 28.8 s: no dock"),
                (WARNING, "injected kill into wall-follower (0.41) at 0.0s"),
                (
                    DEBUG,
                    "datamanager world acknowledged wall #212 to wall-sensor"
                ),
                (DEBUG, "pose (12.50, 1.50) heading 179.9°"),
                (WARNING, "collision at (1.00, 2.00)"),
            ]
        );
        assert_eq!(logs[0].name, "n");
        assert_eq!(logs[2].timestamp, Time { sec: 30, nsec: 0 });
    }
}
