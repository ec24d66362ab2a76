//! The script's text form (round trip, errors naming what was wrong), its
//! link filter on made-up packets, and the rig's bus plan from a script.

use super::*;
use firelink_host::port::{Direction, LinkFilter, Verdict};
use proptest::prelude::*;

fn moment() -> impl Strategy<Value = FaultMoment> {
    prop_oneof![
        Just(FaultMoment::Start),
        (0u64..1 << 40).prop_map(|us| FaultMoment::After(SimDuration::from_micros(us))),
        any::<u64>().prop_map(FaultMoment::Cycle),
    ]
}

fn fault() -> impl Strategy<Value = ScriptedFault> {
    let board = prop_oneof![
        any::<u8>().prop_map(BoardFault::Mute),
        any::<u8>().prop_map(BoardFault::Unplug),
    ]
    .prop_map(ScriptedFault::Board);
    let select = (
        proptest::option::of(0u8..16),
        proptest::option::of(any::<u8>()),
        proptest::option::of(any::<u16>()),
    )
        .prop_map(|(t, dest, offset)| PacketSelector {
            tcode: t.map(Tcode::from),
            dest,
            offset,
        });
    let occurrence = prop_oneof![
        (0.0f64..=1.0).prop_map(Occurrence::Rate),
        (1u32..).prop_map(Occurrence::Count),
    ];
    let packets = (any::<bool>(), select, occurrence).prop_map(|(drop, select, occurrence)| {
        ScriptedFault::Packets {
            effect: if drop {
                PacketEffect::Drop
            } else {
                PacketEffect::Corrupt
            },
            select,
            occurrence,
        }
    });
    let pause = (0u64..1 << 40).prop_map(|us| ScriptedFault::HostPause(Duration::from_micros(us)));
    prop_oneof![board, packets, pause]
}

proptest! {
    /// Display then parse gives the same script back.
    #[test]
    fn text_round_trips(entries in proptest::collection::vec((moment(), fault()), 0..6)) {
        let script = FaultScript {
            entries: entries.into_iter().map(|(at, fault)| ScriptEntry { at, fault }).collect(),
        };
        let text = script.to_string();
        prop_assert_eq!(text.parse::<FaultScript>(), Ok(script), "{}", text);
    }

    /// Any text parses or is refused; it never panics.
    #[test]
    fn any_text_is_parsed_or_refused(text in "[a-z@=:;,0-9x.-]{0,40}") {
        let _ = text.parse::<FaultScript>();
    }
}

#[test]
fn the_docs_examples_parse() {
    let script: FaultScript = "mute@t=0us:id=4; unplug@t=5000000us:id=7;\
         corrupt@start:tcode=0x0,offset=0x1800,count=1;drop@cycle=300:dest=4,rate=0.25;\
         host-pause@cycle=500:for=30000us"
        .parse()
        .unwrap();
    assert_eq!(script.entries.len(), 5);
    assert_eq!(
        script.entries[0],
        ScriptEntry {
            at: FaultMoment::After(SimDuration::ZERO),
            fault: ScriptedFault::Board(BoardFault::Mute(4)),
        }
    );
    // The demo's corrupt-query preset.
    let preset = crate::demo::DemoFault::CorruptQuery.script(std::time::Duration::ZERO);
    assert_eq!(script.entries[2].fault, preset.entries[0].fault);
    assert_eq!(
        script.entries[4],
        ScriptEntry {
            at: FaultMoment::Cycle(500),
            fault: ScriptedFault::HostPause(Duration::from_millis(30)),
        }
    );
    assert_eq!("".parse::<FaultScript>(), Ok(FaultScript::new()));
}

/// Every refusal names the entry and what in it was wrong.
#[test]
fn errors_name_what_was_wrong() {
    let cases = [
        (
            "mute",
            "fault \"mute\": expected KIND@MOMENT[:FIELDS], e.g. mute@t=0us:id=4",
        ),
        (
            "explode@start:id=1",
            "fault \"explode@start:id=1\": unknown kind \"explode\": expected mute, unplug, corrupt, drop or host-pause",
        ),
        (
            "mute@t=5ms:id=1",
            "fault \"mute@t=5ms:id=1\": moment \"t=5ms\": expected start, t=MICROSECONDSus or cycle=N",
        ),
        (
            "mute@start:id=300",
            "fault \"mute@start:id=300\": id=\"300\": a board ID, 0 to 255",
        ),
        (
            "mute@start",
            "fault \"mute@start\": which board? give id=BOARD_ID",
        ),
        (
            "mute@start:id=1,id=2",
            "fault \"mute@start:id=1,id=2\": field \"id=2\": given twice",
        ),
        (
            "mute@start:rate=1",
            "fault \"mute@start:rate=1\": field \"rate=1\": this kind of fault has no such field",
        ),
        (
            "drop@start:tcode=0x10,count=1",
            "fault \"drop@start:tcode=0x10,count=1\": tcode=\"0x10\": a transaction code, 0 to 0xf",
        ),
        (
            "drop@start:rate=1.5",
            "fault \"drop@start:rate=1.5\": rate=\"1.5\": a probability, 0 to 1",
        ),
        (
            "corrupt@start:rate=0.5,count=2",
            "fault \"corrupt@start:rate=0.5,count=2\": how often? give exactly one of rate=P or count=N",
        ),
        (
            "corrupt@start:dest",
            "fault \"corrupt@start:dest\": field \"dest\": expected NAME=VALUE",
        ),
        (
            "host-pause@cycle=x:for=1us",
            "fault \"host-pause@cycle=x:for=1us\": moment \"cycle=x\": expected start, t=MICROSECONDSus or cycle=N",
        ),
    ];
    for (text, message) in cases {
        let e = text.parse::<FaultScript>().unwrap_err();
        assert_eq!(e.to_string(), message, "{text}");
    }
}

/// A write-quadlet request from the host (node 3) to `dest` at `offset`,
/// four header quadlets and a header CRC.
fn request(dest: u8, offset: u16) -> Vec<u8> {
    let q0 = (0xFFC0u32 | u32::from(dest)) << 16;
    let q1 = (0xFFC3u32 << 16) | 0xFFFF;
    let q2 = 0xFFFF_0000 | u32::from(offset);
    [q0, q1, q2, 0x1234_5678, 0]
        .iter()
        .flat_map(|q| q.to_be_bytes())
        .collect()
}

/// A response from `source` to the host.
fn response(source: u8) -> Vec<u8> {
    let q0 = (0xFFC3u32 << 16) | 0x60;
    let q1 = (0xFFC0u32 | u32::from(source)) << 16;
    [q0, q1, 0, 0, 0]
        .iter()
        .flat_map(|q| q.to_be_bytes())
        .collect()
}

/// The filter silences a board by its ID from its moment on, both ways;
/// counted packet rules fire exactly that often on the packets selected.
#[test]
fn the_filter_applies_entries_from_their_moment() {
    let script: FaultScript = "mute@t=10us:id=4;corrupt@start:dest=5,offset=0x1800,count=2"
        .parse()
        .unwrap();
    // Board 4 at node 0, board 5 at node 1.
    let (mut filter, handle) = ScriptFilter::new(&script, &[(4, 0), (5, 1)], 1_000, 7).unwrap();
    // Times are picoseconds on the port's clock: 10 us after 1 ns.
    let mut to4 = request(0, 0);
    assert_eq!(
        filter.packet(5_000_000, Direction::Sent, &mut to4),
        Verdict::Pass
    );
    assert_eq!(
        filter.packet(10_000_999, Direction::Received, &mut response(0)),
        Verdict::Pass
    );
    assert_eq!(
        filter.packet(10_001_000, Direction::Sent, &mut to4),
        Verdict::Drop
    );
    assert_eq!(
        filter.packet(10_001_000, Direction::Received, &mut response(0)),
        Verdict::Drop
    );
    assert_eq!(
        filter.packet(10_001_000, Direction::Received, &mut response(1)),
        Verdict::Pass
    );
    let clean = request(1, 0x1800);
    let mut hurt = 0;
    for _ in 0..5 {
        let mut p = clean.clone();
        assert_eq!(
            filter.packet(20_000_000, Direction::Sent, &mut p),
            Verdict::Pass
        );
        hurt += usize::from(p != clean);
        // Another offset is never touched.
        let mut other = request(1, 0x1000);
        let before = other.clone();
        filter.packet(20_000_000, Direction::Sent, &mut other);
        assert_eq!(other, before);
    }
    assert_eq!(hurt, 2);
    let c = handle.counts();
    assert_eq!((c.silenced, c.corrupted, c.dropped), (2, 2, 0));
    assert_eq!(c.packets, 15);
}

/// `cycle=` entries wait for the servo loop's cycle; a board not in the
/// map is refused by ID.
#[test]
fn cycle_entries_wait_for_the_loop_and_boards_must_exist() {
    let script: FaultScript = "drop@cycle=3:rate=1".parse().unwrap();
    let (mut filter, handle) = ScriptFilter::new(&script, &[(0, 0)], 0, 1).unwrap();
    let mut p = request(0, 0);
    handle.set_cycle(2);
    assert_eq!(filter.packet(0, Direction::Sent, &mut p), Verdict::Pass);
    handle.set_cycle(3);
    assert_eq!(filter.packet(0, Direction::Sent, &mut p), Verdict::Drop);
    assert_eq!(handle.counts().dropped, 1);
    let e = ScriptFilter::new(&"unplug@start:id=9".parse().unwrap(), &[(0, 0)], 0, 1)
        .err()
        .unwrap();
    assert_eq!(e.to_string(), "unplugged board 9: no such board on the rig");
}

fn qla(ids: &[u8]) -> crate::rig::RigBuilder {
    use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
    crate::rig::RigBuilder::qla(
        ids.iter()
            .map(|&id| BoardConfig::new(id, Hardware::Qla1, Profile::Rev8))
            .collect(),
    )
}

/// The rig resolves a script's boards by ID: a board's loss is held at
/// its offset from the fault moment; a board it does not have, and what
/// the bus cannot do by itself, are refused by name.
#[test]
fn the_rig_turns_a_script_into_the_bus_plan() {
    use firelink_bus::TimedFault;
    let script: FaultScript = "unplug@t=2000us:id=6;corrupt@start:dest=5,rate=0.5"
        .parse()
        .unwrap();
    let mut rig = qla(&[4, 5, 6]).fault_script(&script).build().unwrap();
    let six = rig.node(6).unwrap();
    assert_eq!(
        rig.take_pending(),
        [(
            SimDuration::from_millis(2),
            TimedFault::Disconnect {
                node: six,
                reconnect_after: None
            }
        )]
    );
    let e = qla(&[4])
        .fault_script(&"mute@start:id=5".parse().unwrap())
        .build()
        .err()
        .unwrap();
    assert_eq!(e.to_string(), "muted board 5: no such board on the rig");
    for (text, why) in [
        ("drop@cycle=3:rate=1", "does not count servo cycles"),
        (
            "drop@t=5us:rate=1",
            "a packet rule from a later moment is the servo loop's",
        ),
        ("host-pause@start:for=5us", "the host pauses itself"),
    ] {
        let e = qla(&[4])
            .fault_script(&text.parse().unwrap())
            .build()
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains(text) && e.contains(why), "{e}");
    }
}

/// `firelink emulate`'s fault flags are a script: rates from the start,
/// the unplugged and the muted board at the fault moment.
#[test]
fn the_emulate_flags_are_a_script() {
    let faults = crate::rig::served::BusFaults {
        drop_rate: 0.01,
        corrupt_rate: 0.02,
        unplug_board: Some(3),
        mute_board: Some(4),
        ..Default::default()
    };
    assert_eq!(
        faults.script().to_string(),
        "drop@start:rate=0.01;corrupt@start:rate=0.02;unplug@t=0us:id=3;mute@t=0us:id=4"
    );
    assert!(crate::rig::served::BusFaults::default().script().is_empty());
}

/// A timed packet rule on a port whose clock is the host's
/// ([`HostClockedPort`](crate::rig::HostClockedPort)) fires at the host's
/// time: the wrapped port's own clock (here always 0, as a wall clock
/// that lags a host running faster than real time) is not the one it
/// counts on.
#[test]
fn a_timed_packet_rule_on_a_host_clocked_port_counts_the_hosts_time() {
    use crate::rig::{HostClock, HostClockedPort};
    use firelink_host::Port as _;
    let script: FaultScript = "drop@t=500us:rate=1".parse().unwrap();
    let mut port = HostClockedPort::new(FilterPort::new(true), HostClock::new());
    FaultTarget::link()
        .apply_all(&script, &mut port, &[])
        .unwrap();
    assert!(
        port.inner_mut().send(request(0, 0)),
        "dropped before 500 us"
    );
    port.wait(Duration::from_micros(499));
    assert!(port.inner_mut().send(request(0, 0)), "dropped at 499 us");
    port.wait(Duration::from_micros(1));
    assert!(
        !port.inner_mut().send(request(0, 0)),
        "not dropped at 500 us"
    );
}

/// A port that does no I/O: it keeps the link filters a fault target adds
/// (or refuses them, as the Ethernet-only network's port does), so that a
/// test can put made-up packets through them.
struct FilterPort {
    takes_filters: bool,
    filters: firelink_host::port::LinkFilters,
}

impl FilterPort {
    fn new(takes_filters: bool) -> FilterPort {
        FilterPort {
            takes_filters,
            filters: Default::default(),
        }
    }

    /// Send `packet` through the filters: whether it passed.
    fn send(&mut self, mut packet: Vec<u8>) -> bool {
        self.filters.outgoing(0, &mut packet) == Verdict::Pass
    }
}

impl firelink_host::Port for FilterPort {
    fn name(&self) -> &str {
        "filter-port"
    }
    fn read_quadlet(&mut self, _: firelink_host::Dest, _: u64) -> firelink_host::Result<u32> {
        Err(firelink_host::HostError::InvalidRequest {
            what: "a filter port does no I/O",
            value: 0,
        })
    }
    fn write_quadlet(
        &mut self,
        _: firelink_host::Dest,
        _: u64,
        _: u32,
    ) -> firelink_host::Result<()> {
        Ok(())
    }
    fn read_block(
        &mut self,
        _: firelink_host::Dest,
        _: u64,
        _: &mut [u8],
    ) -> firelink_host::Result<()> {
        Err(firelink_host::HostError::InvalidRequest {
            what: "a filter port does no I/O",
            value: 0,
        })
    }
    fn write_block(
        &mut self,
        _: firelink_host::Dest,
        _: u64,
        _: &[u8],
    ) -> firelink_host::Result<()> {
        Ok(())
    }
    fn wait(&mut self, _: Duration) {}
    fn now(&self) -> Duration {
        Duration::ZERO
    }
    fn generation(&self) -> u32 {
        0
    }
    fn add_link_filter(&mut self, filter: Box<dyn LinkFilter>) -> firelink_host::Result<()> {
        if !self.takes_filters {
            return Err(firelink_host::HostError::InvalidRequest {
                what: "this port does not show its packets to filters",
                value: 0,
            });
        }
        self.filters.add(filter);
        Ok(())
    }
    fn takes_link_filters(&self) -> bool {
        self.takes_filters
    }
}

/// `check` refuses before the run what `apply` would refuse later: packet
/// rules on a port that takes no link filters, a `dest=` board the scan
/// did not find, the simulated bus's target on another port.
#[test]
fn check_refuses_what_apply_would_refuse_later() {
    let drop: FaultScript = "drop@start:rate=0.5".parse().unwrap();
    let link = FaultTarget::link();
    let e = link
        .check(&drop, &FilterPort::new(false), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("drop@start:rate=0.5 cannot be applied on filter-port")
            && e.contains("does not show its packets"),
        "{e}"
    );
    // ... which `apply` refuses too.
    let mut no_filters = FilterPort::new(false);
    assert!(link.apply_all(&drop, &mut no_filters, &[]).is_err());
    assert!(link.check(&drop, &FilterPort::new(true), None).is_ok());
    let to_nine: FaultScript = "drop@start:dest=9,rate=1".parse().unwrap();
    let port = FilterPort::new(true);
    // Unknown before the scan; refused once the scan has not found it.
    assert!(link.check(&to_nine, &port, None).is_ok());
    let e = link
        .check(&to_nine, &port, Some(&[(0, 0), (1, 1)]))
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "packets' destination board 9: no such board on the rig"
    );
    assert!(link.check(&to_nine, &port, Some(&[(9, 2)])).is_ok());
    // The rig's target applies faults on its simulated bus only.
    let rig = qla(&[4]).build().unwrap();
    let e = rig
        .fault_target()
        .check(&"mute@start:id=4".parse().unwrap(), &port, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("simulated bus's target on another port"), "{e}");
    let target = rig.fault_target();
    let sim = rig.sim_port();
    assert!(
        target
            .check(&"mute@start:id=4".parse().unwrap(), &sim, None)
            .is_ok()
    );
}

/// A packet rule aimed at a board that is off the bus is refused, naming
/// it (the bus's rule would otherwise have no destination: every board).
#[test]
fn a_packet_rule_for_an_unplugged_board_is_refused() {
    let rig = qla(&[4, 5, 6]).build().unwrap();
    let boards = rig.boards.clone();
    let mut port = rig.sim_port();
    let bus = port.bus_mut();
    apply_on_bus(
        bus,
        &boards,
        ScriptedFault::Board(BoardFault::Unplug(4)),
        SimDuration::ZERO,
    )
    .unwrap();
    bus.run_until(bus.now() + SimDuration::from_millis(5));
    let to = |board: u8| ScriptedFault::Packets {
        effect: PacketEffect::Drop,
        select: PacketSelector {
            dest: Some(board),
            ..PacketSelector::default()
        },
        occurrence: Occurrence::Count(1),
    };
    let e = apply_on_bus(bus, &boards, to(4), SimDuration::ZERO).unwrap_err();
    assert_eq!(
        e.to_string(),
        "configuration: packets to board 4 cannot be dropped: board 4 is off the bus (unplugged)"
    );
    // Board 4 is the chain's leaf (the PC at the other end): its cable
    // takes it alone; the boards still on the bus take the rule.
    let on_bus: Vec<u8> = boards
        .iter()
        .filter(|(_, n)| bus.phy_id(*n).is_some())
        .map(|(id, _)| *id)
        .collect();
    assert!(!on_bus.is_empty() && !on_bus.contains(&4), "{on_bus:?}");
    for id in on_bus {
        apply_on_bus(bus, &boards, to(id), SimDuration::ZERO).unwrap();
    }
}

/// Which of 64 made-up requests a filter drops.
fn drops(port: &mut FilterPort) -> Vec<bool> {
    (0..64).map(|_| !port.send(request(0, 0))).collect()
}

/// Each link filter draws from its own seed (the run's, mixed with the
/// entry's index): two `rate=` rules do not drop the same packets, and
/// the same seed drops the same ones again.
#[test]
fn link_filters_draw_from_the_runs_seed_and_their_entry() {
    let script: FaultScript = "drop@start:rate=0.5;drop@start:rate=0.5".parse().unwrap();
    let run = |seed: u64, entry: usize| {
        let mut port = FilterPort::new(true);
        let target = FaultTarget::link().with_seed(seed);
        target
            .apply(entry, &script.entries[entry], &mut port, &[])
            .unwrap();
        drops(&mut port)
    };
    let (first, second) = (run(7, 0), run(7, 1));
    assert_ne!(first, second, "two rate= rules drew the same sequence");
    assert_eq!(first, run(7, 0), "the same seed did not give the same run");
    assert_ne!(first, run(8, 0), "another seed gave the same run");
    // Both filters on one port, as a run puts them: reproduced too.
    let both = |seed| {
        let mut port = FilterPort::new(true);
        FaultTarget::link()
            .with_seed(seed)
            .apply_all(&script, &mut port, &[])
            .unwrap();
        drops(&mut port)
    };
    assert_eq!(both(7), both(7));
}

/// Faults injected one after another (the service's, as the web console
/// does it) do not lengthen the port's filter chain: a `count=` filter
/// that has fired is let go when the next comes; one that goes on for
/// good stays.
#[test]
fn many_injections_do_not_grow_the_filter_chain() {
    let query = crate::demo::DemoFault::CorruptQuery.script(Duration::from_millis(20));
    let target = FaultTarget::link();
    let mut port = FilterPort::new(true);
    for _ in 0..50 {
        target.apply_all(&query, &mut port, &[]).unwrap();
        assert_eq!(port.filters.len(), 1);
        // The query it corrupts goes by.
        port.send(request(0, 0x1800));
    }
    let rate: FaultScript = "drop@start:rate=0.1".parse().unwrap();
    target.apply_all(&rate, &mut port, &[]).unwrap();
    target.apply_all(&query, &mut port, &[]).unwrap();
    assert_eq!(port.filters.len(), 2, "the rate= filter goes on");
}
