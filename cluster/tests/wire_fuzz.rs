//! Fuzzing the decoders of everything that crosses nodes: valid frames of every remote
//! message type, mutated (bytes flipped, cut, grown, replaced by noise, claimed lengths
//! inflated), must decode or be refused — never panic, never allocate what a frame merely
//! claims. Seeded (xoshiro256**, the project's generator), so a failure replays.

use marie_actors::eo::EoMsg;
use marie_cluster::net::heartbeat::BeatMsg;
use marie_dm::{DmMsg, NewRecord, Payload, Query};
use marie_vocabulary::events::{Event, EventKind};
use marie_vocabulary::run::FaultKind;
use marie_vocabulary::wire::{self, Envelope};
use ractor::message::SerializedMessage;
use ractor::Message;
use rand_xoshiro::rand_core::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256StarStar;

/// Mutants per seed frame.
const ROUNDS: usize = 20_000;

/// The (variant, args) of a cast.
fn cast_parts<M: Message>(msg: M) -> (String, Vec<u8>) {
    match msg.serialize().expect("serializes") {
        SerializedMessage::Cast { variant, args, .. } => (variant, args),
        _ => panic!("not a cast"),
    }
}

/// Valid casts of the remote message types, as (type, variant, args).
fn seeds() -> Vec<(&'static str, String, Vec<u8>)> {
    let record = NewRecord::new("sonar", Payload::from_bytes(vec![1, 2, 3]))
        .with_sub1("front")
        .with_source("ultrasonic");
    let mut out = Vec::new();
    let (v, a) = cast_parts(DmMsg::Put {
        record: record.clone(),
    });
    out.push(("dm", v, a));
    let (v, a) = cast_parts(DmMsg::PutBatch {
        records: vec![
            record.clone(),
            NewRecord::new("odometry", Payload::from_bytes(vec![9])),
            record,
        ],
    });
    out.push(("dm", v, a));
    let (v, a) = cast_parts(EoMsg::Suspend { epoch: 7 });
    out.push(("eo", v, a));
    let (v, a) = cast_parts(EoMsg::Inject {
        fault: FaultKind::Hang,
    });
    out.push(("eo", v, a));
    let frame = Envelope::new("heartbeat", &("alpha", 3u64))
        .unwrap()
        .to_bytes()
        .unwrap();
    let (v, a) = cast_parts(BeatMsg::Beat { frame });
    out.push(("beat", v, a));
    out
}

fn mutate(rng: &mut Xoshiro256StarStar, bytes: &[u8]) -> Vec<u8> {
    let mut b = bytes.to_vec();
    match rng.next_u32() % 6 {
        0 => {
            for _ in 0..=(rng.next_u32() % 4) {
                if !b.is_empty() {
                    let i = rng.next_u32() as usize % b.len();
                    b[i] ^= 1 << (rng.next_u32() % 8);
                }
            }
        }
        1 => b.truncate(rng.next_u32() as usize % (b.len() + 1)),
        2 => b.extend((0..rng.next_u32() % 64).map(|_| rng.next_u32() as u8)),
        3 => {
            b = (0..rng.next_u32() % 128)
                .map(|_| rng.next_u32() as u8)
                .collect();
        }
        4 => {
            // a MessagePack array/map/bin/str header claiming ~4 G elements or bytes
            if !b.is_empty() {
                let i = rng.next_u32() as usize % b.len();
                let header = [0xdd, 0xdf, 0xc6, 0xdb][rng.next_u32() as usize % 4];
                b.splice(i..i, [header, 0xff, 0xff, 0xff, 0xf0]);
            }
        }
        _ => {
            if !b.is_empty() {
                let i = rng.next_u32() as usize % b.len();
                b[i] = [0x00, 0x7f, 0x80, 0xc0, 0xc1, 0xff][rng.next_u32() as usize % 6];
            }
        }
    }
    b
}

#[test]
fn no_mutated_frame_makes_a_decoder_panic() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(0x006d_6172_6965);
    let mut refused = 0usize;
    let mut total = 0usize;
    for (kind, variant, args) in seeds() {
        for _ in 0..ROUNDS {
            let bytes = mutate(&mut rng, &args);
            // sometimes the variant name is garbage too
            let variant = if rng.next_u32() % 8 == 0 {
                String::from_utf8_lossy(&mutate(&mut rng, variant.as_bytes())).into_owned()
            } else {
                variant.clone()
            };
            let msg = || SerializedMessage::Cast {
                variant: variant.clone(),
                args: bytes.clone(),
                metadata: None,
            };
            let ok = match kind {
                "dm" => DmMsg::deserialize(msg()).is_ok(),
                "eo" => EoMsg::deserialize(msg()).is_ok(),
                _ => BeatMsg::deserialize(msg()).is_ok(),
            };
            // the envelope and the event decoders take the same bytes
            let _ = Envelope::from_bytes(&bytes);
            let _ = wire::decode::<Event>(&bytes);
            let _ = wire::decode::<Query>(&bytes);
            refused += usize::from(!ok);
            total += 1;
        }
    }
    // the mutations do break frames (the test would be empty otherwise)
    assert!(refused > total / 4, "{refused} of {total} refused");
}

#[test]
fn a_frame_of_another_protocol_version_is_refused_naming_both_versions() {
    let mut env = Envelope::new("heartbeat", &("alpha", 1u64)).unwrap();
    env.version += 1;
    let err = Envelope::from_bytes(&env.to_bytes().unwrap()).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains(&format!("protocol version {}", env.version))
            && text.contains(&format!(
                "protocol version {}",
                marie_vocabulary::wire::PROTOCOL_VERSION
            )),
        "{text}"
    );
    // events, the other thing nodes will stream, survive the trip
    let event = Event {
        at_ms: 1,
        node: "alpha".into(),
        kind: EventKind::NodeDown {
            peer: "beta".into(),
            silent_ms: 1300,
        },
    };
    let bytes = wire::encode(&event).unwrap();
    assert_eq!(wire::decode::<Event>(&bytes).unwrap(), event);
}
