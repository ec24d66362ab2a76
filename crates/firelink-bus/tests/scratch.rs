//! scratch
use firelink_bus::scenario::*;
use firelink_bus::ArbitrationClass;
#[test]
fn scratch() {
    for p in [Profile::Seed, Profile::Rev7, Profile::Rev8] {
    for class in [ArbitrationClass::Isochronous, ArbitrationClass::Priority, ArbitrationClass::Fair] {
        for g in [63u8, 26, 5] {
            let mut c = CycleConfig::new(8, p, Protocol::Broadcast);
            c.arbitration = class; c.gap_count = Some(g);
            let r = simulate_cycle(&c);
            println!("{:?} {:?} g{} q {:.3} b {:.3} h {:.3} c {:.3} total {:.3} ok {} {:?}", p, class, g, r.phase_us("query").unwrap(), r.phase_us("broadcast").unwrap(), r.phase_us("hub_read").unwrap(), r.phase_us("command").unwrap(), r.total_us, r.boards_ok, r.errors);
        }
    }}
    let mut c = CycleConfig::new(8, Profile::Seed, Protocol::Broadcast);
    c.hub_read_quadlets = Some(272);
    let r = simulate_cycle(&c);
    println!("272: {:.3}", r.phase_us("hub_read").unwrap());
    for n in [2usize,4,8] { for proto in [Protocol::Broadcast, Protocol::Sequential] {
        let mut c = CycleConfig::new(n, Profile::Seed, proto); c.host_overhead = true;
        let r = simulate_cycle(&c);
        println!("host {n} {:?} total {:.2}", proto, r.total_us);
    }}
    let mut c = CycleConfig::new(8, Profile::Seed, Protocol::Broadcast); c.cycle_master = true;
    let r = simulate_cycle(&c); println!("cm: {}", r.table());
}
