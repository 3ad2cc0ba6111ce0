//! Wire form of the interface messages.
//!
//! With ractor's `cluster` feature a message reaches another node only if its type implements
//! `ractor::Message::serialize` / `deserialize`. marie does not use ractor_cluster's derive,
//! whose `BytesConvertable` bound is infallible (a bad frame panics and is dropped in silence);
//! instead [`remote_message!`](crate::remote_message) writes the impl with rmp-serde, so a frame
//! that does not decode is refused with a warning.
//!
//! Each variant travels as its name (the wire tag: never rename a variant, add new ones) and
//! its fields as a MessagePack map (`to_vec_named`, so fields can be added later — as
//! `Option`s: a variant's fields take no `#[serde]` attribute, and a missing field of another
//! type does not decode; see `docs/compatibility.md`). A variant
//! declared with `-> Reply` carries a `reply: RpcReplyPort<Reply>` field and travels as a call:
//! its port is bridged to a byte port and back with [`bridge_out`] / [`bridge_in`].
//!
//! A call's reply port dropped unanswered on the node that received it reaches the caller at
//! once, as a dropped port, as it does between actors of one process: the receiving side
//! sends [`NO_ANSWER`] back in its stead. ractor_cluster sends nothing back for a port dropped
//! there, so without it the caller on another node learned only as its own deadline passed
//! — and a datamanager's replica drops the ports of the callers it cannot answer on purpose,
//! so that they follow the datamanager's name to its leader (a leader deposed, a request it
//! sent on to a leader that is lost, one it kept for want of a leader too long).
//!
//! Frames marie sends between nodes outside ractor's own messages (heartbeats, membership,
//! events) travel in the versioned [`envelope::Envelope`]: a node speaks a
//! [`ProtocolRange`] of versions, agrees with each peer on the highest both speak, and
//! refuses a peer whose range does not meet its own, with an error naming both, never
//! misreading it. The rules of evolution — what may change within a version, what needs a
//! new one — are in `docs/compatibility.md`.

pub mod envelope;
#[cfg(test)]
mod evolution;
pub mod range;

pub use envelope::{Envelope, EnvelopeError, OLDEST_PROTOCOL, PROTOCOL_VERSION};
pub use range::{ProtocolRange, RangeError};

use ractor::concurrency::{self, Duration};
use ractor::RpcReplyPort;
use serde::de::DeserializeOwned;
use serde::Serialize;

/// Encode a value as a MessagePack map.
pub fn encode<T: Serialize + ?Sized>(value: &T) -> Result<Vec<u8>, rmp_serde::encode::Error> {
    rmp_serde::to_vec_named(value)
}

/// Decode MessagePack bytes.
pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, rmp_serde::decode::Error> {
    rmp_serde::from_slice(bytes)
}

fn port_from<T>(tx: concurrency::OneshotSender<T>, timeout: Option<Duration>) -> RpcReplyPort<T> {
    match timeout {
        Some(t) => RpcReplyPort::from((tx, t)),
        None => RpcReplyPort::from(tx),
    }
}

/// The frame a receiving node sends back for a call whose reply port was dropped unanswered
/// there: no bytes, which no MessagePack value encodes to (each is at least one byte). The
/// caller's side drops its own port on it ([`bridge_out`]); a node of a build before it took
/// it for a reply that does not decode, which does the same.
pub const NO_ANSWER: &[u8] = &[];

/// Turn a typed reply port into a byte port for the sending side: bytes that arrive are
/// decoded and forwarded. [`NO_ANSWER`] — the port was dropped unanswered on the other side
/// — and undecodable replies (with a warning) are dropped, which the caller sees as a
/// closed port at once.
pub fn bridge_out<T>(port: RpcReplyPort<T>) -> RpcReplyPort<Vec<u8>>
where
    T: DeserializeOwned + Send + 'static,
{
    let timeout = port.get_timeout();
    let (tx, rx) = concurrency::oneshot::<Vec<u8>>();
    concurrency::spawn(async move {
        let bytes = match timeout {
            Some(t) => concurrency::timeout(t, rx).await.ok().and_then(|r| r.ok()),
            None => rx.await.ok(),
        };
        match bytes {
            Some(bytes) if bytes == NO_ANSWER => {
                tracing::debug!("a call was dropped unanswered on the node that received it")
            }
            Some(bytes) => match decode::<T>(&bytes) {
                Ok(v) => {
                    let _ = port.send(v);
                }
                Err(e) => tracing::warn!(error = %e, "dropping a reply that does not decode"),
            },
            None => {}
        }
    });
    port_from(tx, timeout)
}

/// Turn a byte reply port (from a peer) into a typed port for the receiving actor: the typed
/// answer is encoded and sent back; a port dropped unanswered is sent back as [`NO_ANSWER`],
/// so that the caller hears of it now rather than at its deadline.
pub fn bridge_in<T>(port: RpcReplyPort<Vec<u8>>) -> RpcReplyPort<T>
where
    T: Serialize + Send + 'static,
{
    let timeout = port.get_timeout();
    let (tx, rx) = concurrency::oneshot::<T>();
    concurrency::spawn(async move {
        let answer = match timeout {
            // past the deadline the caller no longer listens: nothing is sent
            Some(t) => match concurrency::timeout(t, rx).await {
                Ok(answer) => answer,
                Err(_) => return,
            },
            None => rx.await,
        };
        match answer {
            Ok(v) => match encode(&v) {
                Ok(bytes) => {
                    let _ = port.send(bytes);
                }
                Err(e) => tracing::warn!(error = %e, "a reply could not be encoded"),
            },
            Err(_) => {
                let _ = port.send(NO_ANSWER.to_vec());
            }
        }
    });
    port_from(tx, timeout)
}

/// Define a message enum whose variants can cross nodes, and implement `ractor::Message` for
/// it with rmp-serde.
///
/// Variants in the enum body are remote: each has named fields that are
/// `Serialize + DeserializeOwned`; `-> R` makes it a call with an extra field
/// `reply: RpcReplyPort<R>`. Variants in the optional `local { .. }` block are for the actor's
/// own use (timers, local-only handles) and refuse to serialize.
///
/// ```
/// use marie_vocabulary::remote_message;
/// remote_message! {
///     /// Messages of a counter.
///     pub enum CounterMsg {
///         /// Add to the count.
///         Add { n: u64 },
///         /// Read the count.
///         Get {} -> u64,
///     }
///     local {
///         /// A timer tick.
///         Tick { generation: u64 },
///     }
/// }
/// let _ = CounterMsg::Add { n: 1 };
/// ```
#[macro_export]
macro_rules! remote_message {
    (
        $(#[$emeta:meta])*
        $vis:vis enum $name:ident {
            $(
                $(#[$vmeta:meta])*
                $variant:ident { $( $(#[$fmeta:meta])* $field:ident : $fty:ty ),* $(,)? } $(-> $reply:ty)?
            ),* $(,)?
        }
        $( local {
            $(
                $(#[$lmeta:meta])*
                $lvariant:ident { $( $(#[$lfmeta:meta])* $lfield:ident : $lfty:ty ),* $(,)? }
            ),* $(,)?
        } )?
    ) => {
        $(#[$emeta])*
        $vis enum $name {
            $(
                $(#[$vmeta])*
                $variant {
                    $( $(#[$fmeta])* $field : $fty, )*
                    $(
                        /// Where the answer goes.
                        reply: ::ractor::RpcReplyPort<$reply>,
                    )?
                },
            )*
            $($(
                $(#[$lmeta])*
                $lvariant { $( $(#[$lfmeta])* $lfield : $lfty, )* },
            )*)?
        }

        impl ::std::fmt::Debug for $name {
            fn fmt(&self, f: &mut ::std::fmt::Formatter<'_>) -> ::std::fmt::Result {
                match self {
                    $( $name::$variant { .. } => f.write_str(stringify!($variant)), )*
                    $($( $name::$lvariant { .. } => f.write_str(stringify!($lvariant)), )*)?
                }
            }
        }

        impl ::ractor::Message for $name {
            fn serializable() -> bool {
                true
            }

            #[allow(unreachable_code, unused_variables)]
            fn serialize(self) -> ::std::result::Result<::ractor::message::SerializedMessage, ::ractor::message::BoxedDowncastErr> {
                let this = self;
                $(
                    #[allow(unreachable_patterns)]
                    let this = $crate::remote_message!(@ser this, $name, $variant, [$($field : $fty),*] $(, $reply)?);
                )*
                ::tracing::warn!(message = ?this, "a local-only message cannot cross nodes");
                Err(::ractor::message::BoxedDowncastErr)
            }

            #[allow(unused_variables)]
            fn deserialize(m: ::ractor::message::SerializedMessage) -> ::std::result::Result<Self, ::ractor::message::BoxedDowncastErr> {
                use ::ractor::message::SerializedMessage;
                match m {
                    SerializedMessage::Cast { variant, args, .. } => {
                        $( $crate::remote_message!(@de_cast variant, args, $name, $variant, [$($field : $fty),*] $(, $reply)?); )*
                        ::tracing::warn!(message = stringify!($name), %variant, "unknown cast variant dropped");
                        Err(::ractor::message::BoxedDowncastErr)
                    }
                    SerializedMessage::Call { variant, args, reply, .. } => {
                        $( $crate::remote_message!(@de_call variant, args, reply, $name, $variant, [$($field : $fty),*] $(, $reply)?); )*
                        ::tracing::warn!(message = stringify!($name), %variant, "unknown call variant dropped");
                        Err(::ractor::message::BoxedDowncastErr)
                    }
                    _ => Err(::ractor::message::BoxedDowncastErr),
                }
            }
        }
    };

    // serialize one variant: returns early on a match, else yields the message back
    (@ser $this:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*], $reply:ty) => {
        match $this {
            $name::$variant { $($field,)* reply } => {
                #[derive(::serde::Serialize)]
                struct Wire<'a> { $( $field: &'a $fty, )* #[serde(skip)] _p: ::std::marker::PhantomData<&'a ()> }
                let args = $crate::wire::encode(&Wire { $( $field: &$field, )* _p: ::std::marker::PhantomData })
                    .map_err(|_| ::ractor::message::BoxedDowncastErr)?;
                return Ok(::ractor::message::SerializedMessage::Call {
                    variant: stringify!($variant).to_string(),
                    args,
                    reply: $crate::wire::bridge_out::<$reply>(reply),
                    metadata: None,
                });
            }
            other => other,
        }
    };
    (@ser $this:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*]) => {
        match $this {
            $name::$variant { $($field,)* } => {
                #[derive(::serde::Serialize)]
                struct Wire<'a> { $( $field: &'a $fty, )* #[serde(skip)] _p: ::std::marker::PhantomData<&'a ()> }
                let args = $crate::wire::encode(&Wire { $( $field: &$field, )* _p: ::std::marker::PhantomData })
                    .map_err(|_| ::ractor::message::BoxedDowncastErr)?;
                return Ok(::ractor::message::SerializedMessage::Cast {
                    variant: stringify!($variant).to_string(),
                    args,
                    metadata: None,
                });
            }
            other => other,
        }
    };

    (@de_cast $v:ident, $args:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*], $reply:ty) => {};
    (@de_cast $v:ident, $args:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*]) => {
        if $v == stringify!($variant) {
            #[derive(::serde::Deserialize)]
            struct Wire { $( $field: $fty, )* }
            return match $crate::wire::decode::<Wire>(&$args) {
                Ok(w) => Ok($name::$variant { $( $field: w.$field, )* }),
                Err(e) => {
                    ::tracing::warn!(message = stringify!($name), variant = stringify!($variant), error = %e, "dropping a message that does not decode");
                    Err(::ractor::message::BoxedDowncastErr)
                }
            };
        }
    };
    (@de_call $v:ident, $args:ident, $port:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*]) => {};
    (@de_call $v:ident, $args:ident, $port:ident, $name:ident, $variant:ident, [$($field:ident : $fty:ty),*], $reply:ty) => {
        if $v == stringify!($variant) {
            #[derive(::serde::Deserialize)]
            struct Wire { $( $field: $fty, )* }
            return match $crate::wire::decode::<Wire>(&$args) {
                Ok(w) => Ok($name::$variant { $( $field: w.$field, )* reply: $crate::wire::bridge_in::<$reply>($port) }),
                Err(e) => {
                    ::tracing::warn!(message = stringify!($name), variant = stringify!($variant), error = %e, "dropping a call that does not decode");
                    Err(::ractor::message::BoxedDowncastErr)
                }
            };
        }
    };
}

#[cfg(test)]
mod tests {
    use ractor::message::SerializedMessage;
    use ractor::Message;

    crate::remote_message! {
        /// Test messages.
        enum TestMsg {
            /// A cast.
            Add { n: u64, label: String },
            /// A call.
            Get { key: String } -> Vec<u32>,
            /// A call without fields.
            Ping {} -> (),
        }
        local {
            /// Local only.
            Tick { generation: u64 },
        }
    }

    #[test]
    fn cast_round_trips() {
        let wire = TestMsg::Add {
            n: 7,
            label: "x".into(),
        }
        .serialize()
        .unwrap();
        match TestMsg::deserialize(wire).unwrap() {
            TestMsg::Add { n, label } => assert_eq!((n, label.as_str()), (7, "x")),
            other => panic!("wrong variant {other:?}"),
        }
    }

    #[tokio::test]
    async fn call_reply_crosses_the_bridge() {
        let (tx, rx) = ractor::concurrency::oneshot();
        let wire = TestMsg::Get {
            key: "k".into(),
            reply: tx.into(),
        }
        .serialize()
        .unwrap();
        assert!(matches!(wire, SerializedMessage::Call { .. }));
        match TestMsg::deserialize(wire).unwrap() {
            TestMsg::Get { key, reply } => {
                assert_eq!(key, "k");
                reply.send(vec![1, 2, 3]).unwrap();
            }
            other => panic!("wrong variant {other:?}"),
        }
        assert_eq!(rx.await.unwrap(), vec![1, 2, 3]);
    }

    /// A call whose port has a deadline of `deadline`, as the receiving node gets it, and the
    /// caller's end. Between the two byte ports stands what ractor_cluster does: the
    /// receiving node's session sends back the bytes of an answer, and nothing for a port
    /// dropped there; the caller's node holds the caller's byte port until its deadline.
    fn call_across(
        deadline: std::time::Duration,
    ) -> (
        ractor::RpcReplyPort<Vec<u32>>,
        ractor::concurrency::OneshotReceiver<Vec<u32>>,
    ) {
        let (tx, rx) = ractor::concurrency::oneshot();
        let wire = TestMsg::Get {
            key: "k".into(),
            reply: (tx, deadline).into(),
        }
        .serialize()
        .unwrap();
        let SerializedMessage::Call {
            variant,
            args,
            reply: callers,
            metadata,
        } = wire
        else {
            panic!("not a call");
        };
        let (there, bytes) = ractor::concurrency::oneshot::<Vec<u8>>();
        tokio::spawn(async move {
            match tokio::time::timeout(deadline, bytes).await {
                Ok(Ok(bytes)) => {
                    let _ = callers.send(bytes);
                }
                _ => tokio::time::sleep(deadline).await,
            }
        });
        let arrived = SerializedMessage::Call {
            variant,
            args,
            reply: (there, deadline).into(),
            metadata,
        };
        match TestMsg::deserialize(arrived).unwrap() {
            TestMsg::Get { reply, .. } => (reply, rx),
            other => panic!("wrong variant {other:?}"),
        }
    }

    #[tokio::test(start_paused = true)]
    async fn an_answer_crosses_the_nodes() {
        let (reply, rx) = call_across(std::time::Duration::from_secs(60));
        reply.send(vec![4, 2]).unwrap();
        assert_eq!(rx.await.unwrap(), vec![4, 2]);
    }

    #[tokio::test(start_paused = true)]
    async fn a_port_dropped_unanswered_closes_the_callers_port_at_once() {
        let deadline = std::time::Duration::from_secs(60);
        let (reply, rx) = call_across(deadline);
        let asked = tokio::time::Instant::now();
        drop(reply);
        // (the clock is paused: it moves only when every task waits for a timer, so a port
        // closed at its deadline would show 60 s gone)
        assert!(rx.await.is_err(), "no answer, and the port closed");
        assert!(
            asked.elapsed() < deadline,
            "closed at once, not at the deadline"
        );
    }

    #[tokio::test(start_paused = true)]
    async fn a_port_neither_answered_nor_dropped_closes_at_the_callers_deadline() {
        let deadline = std::time::Duration::from_secs(60);
        let (reply, rx) = call_across(deadline);
        let asked = tokio::time::Instant::now();
        assert!(rx.await.is_err());
        assert!(asked.elapsed() >= deadline);
        drop(reply);
    }

    #[test]
    fn no_value_encodes_to_the_frame_of_no_answer() {
        assert_ne!(super::encode(&()).unwrap(), super::NO_ANSWER);
        assert_ne!(super::encode(&Vec::<u32>::new()).unwrap(), super::NO_ANSWER);
        assert_ne!(super::encode(&"").unwrap(), super::NO_ANSWER);
        assert_ne!(super::encode(&None::<u8>).unwrap(), super::NO_ANSWER);
    }

    #[test]
    fn local_variants_and_garbage_are_refused() {
        let tick = TestMsg::Tick { generation: 1 };
        assert!(matches!(tick, TestMsg::Tick { generation: 1 }));
        assert!(tick.serialize().is_err());
        let garbage = SerializedMessage::Cast {
            variant: "Add".into(),
            args: vec![0xc1, 0xff],
            metadata: None,
        };
        assert!(TestMsg::deserialize(garbage).is_err());
        let unknown = SerializedMessage::Cast {
            variant: "Renamed".into(),
            args: vec![],
            metadata: None,
        };
        assert!(TestMsg::deserialize(unknown).is_err());
    }
}
