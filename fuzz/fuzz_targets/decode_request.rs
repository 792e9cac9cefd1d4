//! Feeds arbitrary bytes to the protocol decoder as a `Request`: the first thing the
//! server does with every payload that arrives from outside. Holds: no panic, bad bytes
//! are an error, and what decodes encodes to bytes that decode to the same request.
#![no_main]

use arena_protocol::{Request, decode, encode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|bytes: &[u8]| {
    let Ok(request) = decode::<Request>(bytes) else { return };
    let again = encode(&request);
    let back = decode::<Request>(&again).expect("an encoded request decodes");
    assert_eq!(encode(&back), again, "the request does not round-trip (bytes)");
    // A NaN in an action is not equal to itself; the bytes above still pin it.
    #[allow(clippy::eq_op)]
    let comparable = request == request;
    if comparable {
        assert_eq!(back, request, "the request does not round-trip");
    }
});
