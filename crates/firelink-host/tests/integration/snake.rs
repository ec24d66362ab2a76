//! Seed 001's API against emulated Snake nodes on the simulated bus:
//! discovery beside a QLA board, the block buffers and their valid bits,
//! every Get/Set with the seed's conventions, and bad inputs refused with
//! errors that say what was wrong.

use std::time::Duration;

use firelink_board::qla::config::{BoardConfig, Hardware, Profile};
use firelink_board::qla::node::BoardNode;
use firelink_board::qla::rig::{BoardRig, RigOptions};
use firelink_board::snake::{SnakeNode, SnakeNodeConfig};
use firelink_bus::Node;
use firelink_host::RobotIo;
use firelink_host::sim::SimPort;
use firelink_host::snake::{EepromIndex, SnakeSystem};
use firelink_host::{HostError, Port};
use firelink_wire::snake::address::{ChannelDevice, SnakeRegister};
use firelink_wire::snake::registers::{
    AdcData, DAC_MIDPOINT, ENCODER_MIDPOINT, PotOutputs, PowerControl, Wiper,
};

/// Snake nodes with board IDs `ids` (and a QLA board, ID 9, after them
/// when `with_qla`) on a simulated bus.
fn system(ids: &[u8], with_qla: bool) -> SnakeSystem<SimPort> {
    let mut nodes: Vec<Box<dyn Node>> = ids
        .iter()
        .map(|&id| {
            Box::new(SnakeNode::new(
                SnakeNodeConfig::new(id).with_seed(u64::from(id)),
            )) as Box<dyn Node>
        })
        .collect();
    if with_qla {
        nodes.push(Box::new(BoardNode::new(BoardConfig::new(
            9,
            Hardware::Qla1,
            Profile::Rev8,
        ))));
    }
    let rig = BoardRig::daisy_chain_nodes(nodes, &RigOptions::default());
    SnakeSystem::open(SimPort::new(rig.bus, rig.host)).unwrap()
}

fn firmware(s: &SnakeSystem<SimPort>, index: usize) -> &firelink_board::snake::SnakeFirmware {
    s.port()
        .bus()
        .node::<SnakeNode>(firelink_bus::NodeHandle(index + 1))
        .unwrap()
        .firmware()
}

#[test]
fn discovery_finds_snake_nodes_beside_other_boards() {
    let s = system(&[4, 1, 3], true);
    let ids: Vec<u8> = s.nodes().iter().map(|n| n.board_id()).collect();
    assert_eq!(ids, [1, 3, 4]);
    assert_eq!(RobotIo::axis_count(&s), 21);
    assert_eq!(RobotIo::axis_index(&s, 3, 6), Some(13));
    assert_eq!(RobotIo::axis_index(&s, 3, 7), None);
    assert_eq!(RobotIo::axis_location(&s, 13), Some((3, 6)));
    assert_eq!(RobotIo::boards(&s), 0b1_1010);
}

#[test]
fn latch_and_apply_with_valid_bits() {
    let mut s = system(&[0, 1], false);
    s.latch_all_inputs();
    assert!(s.report().all_ok());
    let node = s.node_mut(1).unwrap();
    node.set_motor_voltage(3, 0x9000).unwrap();
    node.set_amplifier_enable(3, true).unwrap();
    s.apply_all_outputs();
    let fw = firmware(&s, 1);
    assert_eq!(fw.motor_command(3), Some(0x9000));
    assert_eq!(fw.motor_command(2), Some(DAC_MIDPOINT));
    assert!(fw.amplifier_on(3) && !fw.amplifier_on(2));
    assert_eq!(firmware(&s, 0).motor_command(3), Some(DAC_MIDPOINT));
    // Without a new set, the next apply leaves channel 3 alone (valid bit
    // clear) while channel 5 is written.
    s.node_mut(1).unwrap().set_motor_voltage(5, 0x7000).unwrap();
    s.apply_all_outputs();
    let fw = firmware(&s, 1);
    assert_eq!(fw.motor_command(3), Some(0x9000));
    assert_eq!(fw.motor_command(5), Some(0x7000));
    // The latched status shows the amplifier; the ADC comes with +8192.
    s.latch_all_inputs();
    let n = s.node(1).unwrap();
    assert!(n.amplifier_enabled(3).unwrap());
    assert!(n.timestamp() > 0);
    // The API's ADC values are the latched samples plus 8192.
    let latched = n.input().channel(2).unwrap().adc;
    let pot = n.analog_position(2).unwrap();
    assert_eq!(i32::from(pot), i32::from(latched.pot()) + 8192);
    assert_eq!(
        i32::from(n.motor_current(2).unwrap()),
        i32::from(latched.current()) + 8192
    );
    // A pot near mid-travel reads near the middle of 0..=16383, and the
    // register read at once agrees within the noise.
    let adc = s.adc_register(1, 2);
    assert!(i32::from(pot).abs_diff(i32::from(adc.pot_api())) < 50);
    // Safe outputs: every motor to the midpoint, every amplifier off.
    s.node_mut(1).unwrap().safe_outputs();
    s.apply_all_outputs();
    let fw = firmware(&s, 1);
    assert!((1..=7).all(|c| fw.motor_command(c) == Some(DAC_MIDPOINT)));
    assert!(!fw.amplifier_on(3));
}

/// The ADC register of one channel, read as a quadlet.
trait AdcRead {
    fn adc_register(&mut self, board: u8, ch: u8) -> AdcData;
}

impl AdcRead for SnakeSystem<SimPort> {
    fn adc_register(&mut self, board: u8, ch: u8) -> AdcData {
        let r = SnakeRegister::channel(ch, ChannelDevice::Adc).unwrap();
        AdcData(self.read_register(board, r).unwrap())
    }
}

#[test]
fn immediate_gets_and_sets() {
    let mut s = system(&[2], false);
    // Current limit (the DAC's second channel) and the DAC readback.
    s.set_motor_current(2, 4, 0x4000).unwrap();
    let dac = s.dac(2, 4).unwrap();
    assert_eq!(
        (dac.current_limit(), dac.motor_voltage()),
        (0x4000, DAC_MIDPOINT)
    );
    // Encoder preload and reset.
    s.set_encoder_preload(2, 4, 1234).unwrap();
    s.latch_all_inputs();
    assert_eq!(s.node(2).unwrap().encoder_position(4).unwrap(), 1234);
    s.reset_encoder(2, 4).unwrap();
    s.latch_all_inputs();
    let n = s.node(2).unwrap();
    assert_eq!(n.encoder_position(4).unwrap(), ENCODER_MIDPOINT);
    assert_eq!(n.encoder_counts(4).unwrap(), 0);
    assert!(!n.encoder_overflow(4).unwrap());
    // Wiper and its gain.
    assert_eq!(s.digital_pot_wiper(2, 4).unwrap(), Wiper::NOMINAL);
    s.set_digital_pot_wiper(2, 4, 649).unwrap();
    let w = s.digital_pot_wiper(2, 4).unwrap();
    assert!((w.feedback_gain() - 3.57727).abs() < 1e-5);
    // The torque/speed switch.
    let speed = PotOutputs {
        speed_mode: true,
        o2: false,
    };
    s.set_analog_switches(2, 4, speed).unwrap();
    assert_eq!(s.analog_switches(2, 4).unwrap(), speed);
    assert_eq!(s.analog_switches(2, 5).unwrap(), PotOutputs::default());
    // Power control at once, with its mask.
    s.set_power_control(2, PowerControl::channel(6, true).unwrap())
        .unwrap();
    s.latch_all_inputs();
    assert!(s.node(2).unwrap().amplifier_enabled(6).unwrap());
    // Watchdog.
    s.set_watchdog(firelink_host::WatchdogSetting::from_ms(10.0).unwrap())
        .unwrap();
    let w = s.watchdog(2).unwrap();
    assert!((w.as_secs_f64() - 0.010).abs() < 6e-6, "{w:?}");
}

#[test]
fn eeprom_raw_float_and_write_protection() {
    let mut s = system(&[0], false);
    let at = EepromIndex::new(3, 2).unwrap().index();
    assert_eq!(at, 0x32);
    // Write-protected at power-up: a clear refusal, nothing written.
    let e = s.set_eeprom_raw(0, at, 0xBEEF).unwrap_err();
    assert!(e.to_string().contains("write protection"), "{e}");
    assert_eq!(s.eeprom_raw(0, at).unwrap(), 0);
    assert!(s.write_protect(0, 3).unwrap());
    s.set_write_protect(0, 3, false).unwrap();
    s.set_eeprom_raw(0, at, 0xBEEF).unwrap();
    assert_eq!(s.eeprom_raw(0, at).unwrap(), 0xBEEF);
    // A float in two words.
    for x in [3.57727f32, -0.001, 1.0e9] {
        s.set_eeprom_float(0, 0x3C, x).unwrap();
        assert_eq!(s.eeprom_float(0, 0x3C).unwrap().to_bits(), x.to_bits());
    }
    assert_eq!(s.eeprom_raw(0, 0x3C).unwrap(), 0x4E6E); // 1e9, high word
    // Other channels keep their own EEPROM and protection.
    assert!(s.set_eeprom_float(0, 0x4C, 1.0).is_err());
}

#[test]
fn bad_inputs_are_refused_with_clear_errors() {
    let mut s = system(&[0], false);
    let msg = |r: Result<(), HostError>| r.unwrap_err().to_string();
    // Channels outside 1..=7.
    assert!(msg(s.set_motor_current(0, 8, 0)).contains("channel"));
    assert!(msg(s.set_motor_current(0, 0, 0)).contains("channel"));
    assert!(
        s.node_mut(0)
            .unwrap()
            .set_motor_voltage(9, 0)
            .unwrap_err()
            .to_string()
            .contains("channel (1..=7)")
    );
    // EEPROM words and indices.
    assert!(msg(s.set_eeprom_raw(0, 0x3E, 1)).contains("EEPROM word"));
    assert!(msg(s.set_eeprom_raw(0, 0x83, 1)).contains("channel"));
    assert!(msg(s.set_eeprom_raw(0, 0x123, 1)).contains("EEPROM index"));
    assert!(msg(s.set_eeprom_float(0, 0x3D, 1.0)).contains("0..=12"));
    // The wiper's 10 bits.
    assert!(msg(s.set_digital_pot_wiper(0, 1, 1024)).contains("wiper"));
    // Encoder preload's 24 bits.
    assert!(msg(s.set_encoder_preload(0, 1, 1 << 24)).contains("preload"));
    // A board that is not there.
    assert_eq!(
        s.set_motor_current(5, 1, 0),
        Err(HostError::UnknownBoard(5))
    );
    // An abstract-layer axis beyond the nodes.
    assert!(RobotIo::encoder_position(&s, 7).is_err());
    assert!(RobotIo::set_motor_command(&mut s, 7, 0).is_err());
    // An unimplemented cell is the node's address error.
    let freq = SnakeRegister::channel(1, ChannelDevice::EncoderFrequency).unwrap();
    assert!(matches!(
        s.read_register(0, freq),
        Err(HostError::Rcode { .. })
    ));
}

#[test]
fn a_silent_host_lets_the_watchdog_disable_the_amplifiers() {
    let mut s = system(&[0], false);
    s.set_watchdog(firelink_host::WatchdogSetting::from_ms(2.0).unwrap())
        .unwrap();
    s.node_mut(0).unwrap().set_all_amplifiers(true);
    s.latch_all_inputs();
    s.apply_all_outputs();
    s.latch_all_inputs();
    assert!(s.node(0).unwrap().amplifiers_on(0x7F));
    s.port_mut().wait(Duration::from_millis(3));
    s.latch_all_inputs();
    let n = s.node(0).unwrap();
    assert!(n.status().watchdog_timeout());
    assert!(!n.amplifiers_on(0x01));
    assert!(RobotIo::watchdog_expired(&s, 0));
}
