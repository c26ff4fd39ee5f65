//! What a boat's network does to the bridge, with loopback sockets of the
//! test's own as the other end: a flood of garbage on the UDP port among
//! good sentences; a TCP peer that closes and comes back; input the
//! contract cannot carry. The bridge keeps running, counts every refusal by
//! reason, publishes every fix it could decode and nothing malformed.

mod common;

use std::io::Write;
use std::net::{TcpListener, UdpSocket};
use std::time::Duration;

use common::*;
use twin_bridge::bench::boat_sentences;
use twin_wire::write::nmea0183::sentence;

#[test]
fn a_flood_of_garbage_on_the_udp_port() {
    let port = free_udp_port();
    let bridge = start(&[&format!("nmea0183:udp:127.0.0.1:{port}")]);
    bridge.wait_stats("the socket bound", |s| {
        s.sources.first().is_some_and(|s| s.connected)
    });
    let sentences = boat_sentences(20);
    let expected = expected_fixes(&sentences.join("\r\n"));
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut x: u32 = 12345;
    let mut junk = |len: usize| {
        (0..len)
            .map(|_| {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 24) as u8
            })
            .collect::<Vec<u8>>()
    };
    let mut garbage = 0;
    for (i, s) in sentences.iter().enumerate() {
        // Between two good sentences: random bytes, a sentence with a wrong
        // checksum, and a line far over the length limit.
        for _ in 0..20 {
            sender.send_to(&junk(200), ("127.0.0.1", port)).unwrap();
            garbage += 1;
        }
        let mut wrong = sentence("GPGGA,042720.000,5954.000,N,01042.000,E,1,08,0.9,1.0,M,0.0,M,,");
        wrong.replace_range(wrong.len() - 2.., "00");
        sender
            .send_to(wrong.as_bytes(), ("127.0.0.1", port))
            .unwrap();
        if i % 10 == 0 {
            sender
                .send_to(&vec![b'$'; 10_000], ("127.0.0.1", port))
                .unwrap();
        }
        sender
            .send_to(format!("{s}\r\n").as_bytes(), ("127.0.0.1", port))
            .unwrap();
        std::thread::sleep(Duration::from_millis(2));
    }
    bridge.wait_until("every good fix", |sink| fixes(sink).len() == expected.len());
    let sink = bridge.sink.clone();
    let stats = bridge.stop();
    let got = fixes(&sink);
    assert_eq!(
        got.iter().map(|d| d.value).collect::<Vec<_>>(),
        expected,
        "the good sentences' fixes, all of them"
    );
    let source = &stats.sources[0];
    assert_eq!(source.rejected.get("bad_checksum"), Some(&120));
    assert_eq!(source.rejected.get("line_too_long"), Some(&12));
    let refused: u64 = source.rejected.values().sum();
    assert!(
        refused >= garbage,
        "every garbage datagram refused: {:?}",
        source.rejected
    );
    assert_eq!(source.published.gnss as usize, expected.len());
}

#[test]
fn a_tcp_peer_that_closes_and_comes_back() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    let sentences = boat_sentences(20);
    let expected = expected_fixes(&sentences.join("\r\n"));
    let bridge = start(&[&format!("nmea0183:tcp:127.0.0.1:{port}")]);
    for half in sentences.chunks(sentences.len() / 2) {
        let (mut peer, _) = listener.accept().unwrap();
        for s in half {
            peer.write_all(format!("{s}\r\n").as_bytes()).unwrap();
        }
        // A sentence cut by the close: dropped, not decoded as if whole.
        peer.write_all(b"$GPGGA,0427").unwrap();
        drop(peer);
    }
    bridge.wait_until("every fix", |sink| fixes(sink).len() == expected.len());
    bridge.wait_stats("both closes counted", |s| {
        s.sources
            .first()
            .is_some_and(|s| s.disconnects.get("closed") == Some(&2))
    });
    let sink = bridge.sink.clone();
    let stats = bridge.stop();
    assert_eq!(
        fixes(&sink).iter().map(|d| d.value).collect::<Vec<_>>(),
        expected
    );
    let source = &stats.sources[0];
    // Twice served, and connecting again (the listener's backlog accepts).
    assert!(source.connects >= 2, "{source:?}");
    assert!(source.rejected.is_empty(), "{:?}", source.rejected);
}

#[test]
fn what_the_contract_cannot_carry_is_counted_not_published() {
    // GGA alone: positions without course or speed, which the gnss payload
    // requires.
    let port = free_udp_port();
    let bridge = start(&[&format!("nmea0183:udp:127.0.0.1:{port}")]);
    bridge.wait_stats("the socket bound", |s| {
        s.sources.first().is_some_and(|s| s.connected)
    });
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    for s in boat_sentences(15).iter().filter(|s| s.contains("GGA")) {
        sender.send_to(s.as_bytes(), ("127.0.0.1", port)).unwrap();
    }
    bridge.wait_stats("the fixes counted", |s| {
        s.sources
            .first()
            .is_some_and(|s| s.not_published.get("missing_field") == Some(&15))
    });
    let sink = bridge.sink.clone();
    let stats = bridge.stop();
    assert!(fixes(&sink).is_empty());
    assert_eq!(stats.sources[0].published.gnss, 0);
}
