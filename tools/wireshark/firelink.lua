-- Firelink: a Wireshark dissector for IEEE 1394 asynchronous packets as
-- Firelink writes them and as the JHU FPGA boards' Ethernet bridge sends
-- them, with the dVRK board address map, the Snake node (seed 001) and the
-- MAHRU humanoid's module commands (seed 002).
--
-- Install: copy this file into Wireshark's personal plugin folder
-- (`~/.local/lib/wireshark/plugins/`, see scripts/wireshark-install), or
-- load it for one run: `tshark -X lua_script:tools/wireshark/firelink.lua`.
--
-- What reaches it (UDP ports 1394 and 1395):
-- * Firelink's own pcap files (link type RAW, IPv4/UDP between
--   127.13.94.<physical id> addresses; crates/firelink-wire/src/pcap.rs):
--   the payload is one bare 1394 packet with its CRCs, a one-byte ack, or
--   a PHY packet in its 12-byte link-internal form. Port 1394 on both sides:
--   seen on the bus; 1395 marks a capturing host's own side.
-- * The Ethernet bridge's datagrams (UDP port 1394 on the board), any other
--   addresses: host -> board is a 16-bit control word and a complete 1394
--   packet (its length is 2 modulo 4); board -> host is the 1394 response
--   and 8 bytes of extra data.
--
-- Which robot's meaning an offset has: preference `firelink.robot`
-- (auto, dvrk, snake, mahru). `auto` counts evidence over the capture,
-- each packet before it is decoded, and picks the robot with the most:
-- MAHRU: a block write of 320 bytes to offset 18 (QWRITE), a block read
-- of offset 17 for 32 bytes (QREAD) or of 19 for 24 bytes (FTREAD), an
-- IDREQUEST answer (offset 11, top byte 0x4D); Snake: a block read of
-- offset 0 for 92 bytes (23 quadlets) or a block write of 28 bytes
-- (7 quadlets) there, a version register (offset 4) reading "SNK";
-- dVRK: HW_VERSION (offset 4) reading QLA1, DQLA or dRA1, any access to
-- the hub space (0x1000-0x1FFF),
-- a status broadcast (0xFFFFFF001000...) or the snooped command block
-- (0xFFFFFFFF0000), a real-time block of 12, 28, 32, 52 or 60 quadlets.
-- No evidence (or a tie with dVRK) means dVRK. In one pass (tshark
-- without -2) packets before the first evidence are decoded as dVRK; in
-- two passes (tshark -2, or the Wireshark GUI once the file is loaded)
-- the whole capture's evidence applies to every packet.
--
-- Every read checks its length first: a short or garbled packet gets the
-- expert info "truncated" (or "unknown tcode"), never a Lua error.

local firelink = Proto("firelink", "Firelink IEEE 1394")

---------------------------------------------------------------------------
-- Bit helpers: arithmetic only (Lua 5.2 to 5.4), the CRC through bit32 or
-- Wireshark's `bit` library.

local TWO32 = 4294967296

-- Bits hi..lo of a 32-bit value (an integer on Lua 5.3+ too).
local function bits(v, hi, lo)
    return math.floor(v / 2 ^ lo) % math.floor(2 ^ (hi - lo + 1))
end

local bxor, lshift, rshift
if bit32 then
    bxor, lshift, rshift = bit32.bxor, bit32.lshift, bit32.rshift
else
    bxor = function(a, b) return bit.bxor(a, b) % TWO32 end
    lshift = function(a, n) return bit.lshift(a, n) % TWO32 end
    rshift = function(a, n) return bit.rshift(a, n) % TWO32 end
end

-- CRC-32/BZIP2 (IEEE 1394): generator 0x04C11DB7 MSB first, init all
-- ones, complemented, not reflected.
local crc_table = {}
for i = 0, 255 do
    local c = lshift(i, 24)
    for _ = 1, 8 do
        if c >= 0x80000000 then
            c = bxor(lshift(c, 1), 0x04C11DB7)
        else
            c = lshift(c, 1)
        end
    end
    crc_table[i] = c
end

local function crc1394(tvb, offset, len)
    local c = 0xFFFFFFFF
    local bytes = tvb:raw(offset, len)
    for i = 1, #bytes do
        c = bxor(lshift(c, 8), crc_table[bxor(rshift(c, 24), bytes:byte(i))])
    end
    return bxor(c, 0xFFFFFFFF)
end

---------------------------------------------------------------------------
-- Names.

local TCODE = {
    [0x0] = "write_request_quadlet", [0x1] = "write_request_block",
    [0x2] = "write_response", [0x4] = "read_request_quadlet",
    [0x5] = "read_request_block", [0x6] = "read_response_quadlet",
    [0x7] = "read_response_block", [0x8] = "cycle_start",
    [0x9] = "lock_request", [0xA] = "stream", [0xB] = "lock_response",
    [0xE] = "link_internal",
}
-- Header bytes before the header CRC (the whole packet for link-internal).
local HEADER_LEN = {
    [0x0] = 16, [0x1] = 16, [0x2] = 12, [0x4] = 12, [0x5] = 16, [0x6] = 16,
    [0x7] = 16, [0x8] = 16, [0x9] = 16, [0xA] = 4, [0xB] = 16, [0xE] = 12,
}
local HAS_BLOCK_LENGTH = { [0x1] = true, [0x5] = true, [0x7] = true, [0x9] = true, [0xB] = true }
local HAS_DATA = { [0x1] = true, [0x7] = true, [0x9] = true, [0xB] = true, [0xA] = true }
local IS_REQUEST = { [0x0] = true, [0x1] = true, [0x4] = true, [0x5] = true, [0x9] = true, [0x8] = true }
local IS_RESPONSE = { [0x2] = true, [0x6] = true, [0x7] = true, [0xB] = true }
local RCODE = {
    [0] = "complete", [4] = "conflict_error", [5] = "data_error",
    [6] = "type_error", [7] = "address_error",
}
local ACK = {
    [0x1] = "complete", [0x2] = "pending", [0x4] = "busy_x", [0x5] = "busy_a",
    [0x6] = "busy_b", [0xD] = "data_error", [0xE] = "type_error",
}
local EXT_TCODE = {
    [0] = "none", [1] = "mask_swap", [2] = "compare_swap", [3] = "fetch_add",
    [4] = "little_add", [5] = "bounded_add", [6] = "wrap_add",
}
local CRC_STATUS = { [0] = "good", [1] = "bad", [2] = "not computed" }
local PHY_KIND = { [0] = "PHY configuration", [1] = "link-on", [2] = "self-ID", [3] = "reserved" }
local ROBOTS = { "dvrk", "snake", "mahru" }

local SPACE = {
    [0] = "main registers", [1] = "hub", [2] = "FPGA PROM", [3] = "QLA PROM",
    [4] = "Ethernet", [5] = "FireWire packet buffer", [6] = "1-wire memory",
    [7] = "data collection", [8] = "waveform table",
}
local BOARD_REG = {
    [0] = "STATUS", [1] = "PHY_CTRL", [2] = "PHY_DATA", [3] = "WATCHDOG",
    [4] = "HW_VERSION", [5] = "TEMPERATURE", [6] = "DIGITAL_OUT",
    [7] = "FW_VERSION", [8] = "PROM_CMD", [9] = "PROM_RESULT",
    [10] = "DIGITAL_IN", [11] = "IP_ADDR", [12] = "ETH_STATUS", [15] = "GIT_DESC",
}
local AXIS_REG = {
    [0] = "ADC", [1] = "DAC", [4] = "ENC_PRELOAD", [5] = "ENC_POSITION",
    [6] = "ENC_PERIOD", [7] = "ENC_QTR1", [9] = "ENC_QTR5", [10] = "ENC_RUN",
    [11] = "MOTOR_CONFIG", [12] = "MOTOR_STATUS",
}
local SNAKE_GLOBAL = { [0] = "status", [1] = "phy_control", [2] = "phy_data", [3] = "watchdog", [4] = "version" }
local SNAKE_DEVICE = {
    [0] = "adc", [1] = "dac", [2] = "pot_control", [3] = "pot_data",
    [4] = "encoder_preload", [5] = "encoder", [6] = "encoder_period", [7] = "encoder_frequency",
}
local MAHRU_CMD = {
    [0] = "STOP", [11] = "IDREQUEST", [12] = "IDCHECK", [13] = "PARAMETER",
    [14] = "SETBIAS", [15] = "READY", [16] = "START", [17] = "QREAD",
    [18] = "QWRITE", [19] = "FTREAD",
}
local MAHRU_KIND = { [1] = "motor controller", [2] = "force/torque sensor" }
local MAHRU_STATE = { [0] = "idle", [1] = "parameterized", [2] = "ready", [3] = "running", [4] = "stopped" }

local STATUS_BROADCAST = 0xFFFFFF001000
local COMMAND_SNOOP = 0xFFFFFFFF0000
local MAHRU_TRACE = 0x000100000000

---------------------------------------------------------------------------
-- Fields.

local F = {}
local function field(key, ...)
    F[key] = ...
end
local U32, U16, U8 = ProtoField.uint32, ProtoField.uint16, ProtoField.uint8
local H, D = base.HEX, base.DEC

field("kind", ProtoField.string("firelink.kind", "Capture point"))
field("robot", ProtoField.string("firelink.robot", "Decoded as robot"))
-- Bridge.
field("control", U16("firelink.bridge.control", "Bridge control word", H))
field("control_nf", ProtoField.bool("firelink.bridge.no_forward", "No forward", 16, nil, 0x0100))
field("control_gen", U16("firelink.bridge.generation", "Host's bus generation", D, nil, 0x00FF))
field("extra", ProtoField.bytes("firelink.bridge.extra", "Bridge extra data"))
field("x_flags", U8("firelink.bridge.flags", "Flags", H))
field("x_reset", ProtoField.bool("firelink.bridge.bus_reset", "Bus reset in progress", 8, nil, 0x01))
field("x_dropped", ProtoField.bool("firelink.bridge.packet_dropped", "Packet dropped", 8, nil, 0x02))
field("x_internal", ProtoField.bool("firelink.bridge.internal_error", "Internal error", 8, nil, 0x04))
field("x_summary", ProtoField.bool("firelink.bridge.summary_error", "Summary error", 8, nil, 0x08))
field("x_nf", ProtoField.bool("firelink.bridge.flag_no_forward", "Handled without forwarding", 8, nil, 0x10))
field("x_port", U8("firelink.bridge.source_port", "Source port", D, nil, 0x60))
field("x_gen", U8("firelink.bridge.board_generation", "Board's bus generation", D))
field("x_invalid", U8("firelink.bridge.invalid_states", "Invalid states", D))
field("x_errors", U8("firelink.bridge.packet_errors", "Packet errors", D))
field("x_rx", U16("firelink.bridge.receive_time", "Receive time (49.152 MHz ticks)", D))
field("x_total", U16("firelink.bridge.total_time", "Total time (49.152 MHz ticks)", D))
-- The 1394 packet.
field("ack", U8("firelink.ack", "Ack code", H, ACK, 0xF0))
field("dst", U16("firelink.dst", "Destination ID", H))
field("dst_bus", U16("firelink.dst.bus", "Destination bus", H, nil, 0xFFC0))
field("dst_phy", U16("firelink.dst.phy", "Destination node (physical ID)", D, nil, 0x003F))
field("tlabel", U16("firelink.tlabel", "Transaction label", D, nil, 0xFC00))
field("retry", U16("firelink.retry", "Retry code", D, nil, 0x0300))
field("tcode", U8("firelink.tcode", "Transaction code", H, TCODE, 0xF0))
field("priority", U8("firelink.priority", "Priority", H, nil, 0x0F))
field("src", U16("firelink.src", "Source ID", H))
field("src_bus", U16("firelink.src.bus", "Source bus", H, nil, 0xFFC0))
field("src_phy", U16("firelink.src.phy", "Source node (physical ID)", D, nil, 0x003F))
field("offset", ProtoField.uint64("firelink.offset", "Destination offset", H))
field("rcode", U8("firelink.rcode", "Response code", D, RCODE, 0xF0))
field("quadlet", U32("firelink.quadlet", "Quadlet data", H))
field("data_length", U16("firelink.data_length", "Data length", D))
field("ext_tcode", U16("firelink.extended_tcode", "Extended tcode", D, EXT_TCODE))
field("cycle_time", U32("firelink.cycle_time", "Cycle time", H))
field("stream_channel", U8("firelink.stream.channel", "Channel", D, nil, 0x3F))
field("header_crc", U32("firelink.header_crc", "Header CRC", H))
field("header_crc_status", U8("firelink.header_crc.status", "Header CRC status", D, CRC_STATUS))
field("data", ProtoField.bytes("firelink.data", "Data"))
field("data_crc", U32("firelink.data_crc", "Data CRC", H))
field("data_crc_status", U8("firelink.data_crc.status", "Data CRC status", D, CRC_STATUS))
field("crc_bad", ProtoField.bool("firelink.crc.bad", "CRC bad"))
field("crc_computed", U32("firelink.crc.computed", "Computed CRC", H))
field("request_in", ProtoField.framenum("firelink.request_in", "Request in frame", base.NONE, frametype and frametype.REQUEST))
field("response_to", ProtoField.uint64("firelink.response_to", "Answers a request at offset", H))
-- PHY packets.
field("phy_quadlet", U32("firelink.phy", "PHY packet", H))
field("phy_check", U32("firelink.phy.check", "PHY packet complement", H))
field("phy_kind", U32("firelink.phy.kind", "PHY packet kind", D, PHY_KIND, 0xC0000000))
field("phy_id", U32("firelink.phy.id", "Physical ID", D, nil, 0x3F000000))
field("phy_root", ProtoField.bool("firelink.phy.force_root", "Force root (R)", 32, nil, 0x00800000))
field("phy_set_gap", ProtoField.bool("firelink.phy.set_gap", "Set gap count (T)", 32, nil, 0x00400000))
field("phy_gap", U32("firelink.phy.gap_count", "Gap count", D, nil, 0x003F0000))
field("phy_link", ProtoField.bool("firelink.phy.link_active", "Link active", 32, nil, 0x00400000))
field("phy_speed", U32("firelink.phy.speed", "Speed", D, { [0] = "S100", [1] = "S200", [2] = "S400" }, 0x0000C000))
field("phy_contender", ProtoField.bool("firelink.phy.contender", "Contender", 32, nil, 0x00000800))
field("phy_ports", U32("firelink.phy.ports", "Ports 0-2", H, nil, 0x000000FC))
field("phy_initiated", ProtoField.bool("firelink.phy.initiated_reset", "Initiated reset", 32, nil, 0x00000002))
field("phy_more", ProtoField.bool("firelink.phy.more", "More packets", 32, nil, 0x00000001))
-- Address map (every robot).
field("register", ProtoField.string("firelink.register", "Register"))
field("space", ProtoField.string("firelink.space", "Address space"))
-- dVRK board registers.
field("b_status", U32("firelink.board.status", "STATUS", H))
field("bs_axes", U32("firelink.board.status.axes", "Axes", D, nil, 0xF0000000))
field("bs_id", U32("firelink.board.status.board_id", "Board ID", D, nil, 0x0F000000))
field("bs_wdog", ProtoField.bool("firelink.board.status.watchdog_timeout", "Watchdog timed out", 32, nil, 0x00800000))
field("bs_qdac", ProtoField.bool("firelink.board.status.quad_dac", "Quad DAC present", 32, nil, 0x00400000))
field("bs_supply", ProtoField.bool("firelink.board.status.supply_good", "Motor supply good", 32, nil, 0x00080000))
field("bs_power", ProtoField.bool("firelink.board.status.power_enabled", "Motor power enabled", 32, nil, 0x00040000))
field("bs_relay_state", ProtoField.bool("firelink.board.status.relay_state", "Safety relay state", 32, nil, 0x00020000))
field("bs_relay_on", ProtoField.bool("firelink.board.status.relay_on", "Safety relay on", 32, nil, 0x00010000))
field("bs_fault", ProtoField.bool("firelink.board.status.supply_fault", "Motor supply fault", 32, nil, 0x00008000))
field("bs_feedback", ProtoField.bool("firelink.board.status.safety_feedback", "Safety feedback", 32, nil, 0x00004000))
field("bs_ioexp", ProtoField.bool("firelink.board.status.io_expander", "I/O expander present", 32, nil, 0x00001000))
field("bs_ampfault", U32("firelink.board.status.amp_fault", "Amplifier fault per axis (Rev < 8)", H, nil, 0x00000F00))
field("bs_safety", U32("firelink.board.status.safety_amp_disable", "Safety amplifier disable", H, nil, 0x000000F0))
field("bs_amp", U32("firelink.board.status.amp_enable", "Amplifier enabled per axis", H, nil, 0x0000000F))
field("b_status_write", U32("firelink.board.status_write", "STATUS write (mask/value pairs)", H))
field("b_hw", ProtoField.string("firelink.board.hw_version", "HW_VERSION"))
field("b_fw", U32("firelink.board.fw_version", "FW_VERSION", D))
field("b_wdog", U32("firelink.board.watchdog", "WATCHDOG period (5.208 us units)", D, nil, 0x0000FFFF))
field("b_din", U32("firelink.board.digital_in", "DIGITAL_IN", H))
field("b_temp", U32("firelink.board.temperature", "TEMPERATURE", H))
field("b_ip", ProtoField.ipv4("firelink.board.ip_addr", "IP_ADDR"))
field("b_reg", U32("firelink.board.value", "Register value", H))
field("b_id", U8("firelink.board.id", "Board ID", D))
field("b_timestamp", U32("firelink.board.timestamp", "Timestamp (49.152 MHz clocks)", D))
-- dVRK axes.
field("axis", U8("firelink.axis", "Axis", D))
field("a_pot", U32("firelink.axis.pot", "Potentiometer", D, nil, 0xFFFF0000))
field("a_cur", U32("firelink.axis.current", "Motor current", D, nil, 0x0000FFFF))
field("a_dac", U32("firelink.axis.dac", "DAC", H))
field("a_dac_valid", ProtoField.bool("firelink.axis.dac.valid", "Valid", 32, nil, 0x80000000))
field("a_dac_mask", ProtoField.bool("firelink.axis.dac.amp_enable_mask", "Amplifier enable mask (Rev 8)", 32, nil, 0x20000000))
field("a_dac_en", ProtoField.bool("firelink.axis.dac.amp_enable", "Amplifier enable (Rev 8)", 32, nil, 0x10000000))
field("a_dac_board", U32("firelink.axis.dac.board_id", "Board ID (Rev 4/7)", D, nil, 0x0F000000))
field("a_dac_cmd", U32("firelink.axis.dac.command", "Command", H, nil, 0x0000FFFF))
field("a_enc", U32("firelink.axis.encoder", "Encoder position", H, nil, 0x00FFFFFF))
field("a_enc_raw", U32("firelink.axis.encoder.raw", "ENC_POSITION", H))
field("a_period", U32("firelink.axis.period", "Encoder period", H))
field("a_qtr1", U32("firelink.axis.qtr1", "Encoder quarter 1", H))
field("a_qtr5", U32("firelink.axis.qtr5", "Encoder quarter 5", H))
field("a_run", U32("firelink.axis.run", "Encoder running counter", H))
field("a_mstatus", U32("firelink.axis.motor_status", "MOTOR_STATUS", H))
field("a_reg", U32("firelink.axis.value", "Axis register value", H))
-- dVRK broadcast protocol.
field("q_seq", U32("firelink.bcast.seq", "Query sequence", D, nil, 0xFFFF0000))
field("q_mask", U32("firelink.bcast.board_mask", "Board mask", H, nil, 0x0000FFFF))
field("sb_seq", U32("firelink.bcast.status_seq", "Status broadcast sequence", D, nil, 0xFFFF0000))
field("sb_size", U32("firelink.bcast.status_quadlets", "Status broadcast quadlets", D, nil, 0x0000FFFF))
field("hub_board", ProtoField.bytes("firelink.hub.board", "Hub entry"))
field("hub8_size", U32("firelink.hub.size", "Quadlets", D, nil, 0xFF000000))
field("hub8_seq", U32("firelink.hub.seq_low", "Sequence low byte", D, nil, 0x00FF0000))
field("hub8_err", ProtoField.bool("firelink.hub.seq_error", "Sequence error", 32, nil, 0x00008000))
field("hub8_time", U32("firelink.hub.update_time", "Update time", D, nil, 0x00007FFF))
field("hub7_seq", U32("firelink.hub.seq", "Sequence", D, nil, 0xFFFF0000))
field("hub7_time", U32("firelink.hub.time", "Time", D, nil, 0x0000FFFF))
field("hub_read_start", U32("firelink.hub.timing.read_start", "Hub read start", D, nil, 0xFFFF0000))
field("hub_now", U32("firelink.hub.timing.now", "Now", D, nil, 0x0000FFFF))
field("wb_header", U32("firelink.wblock.header", "Write block header", H))
field("wb_board", U32("firelink.wblock.board_id", "Board ID", D, nil, 0x0000FF00))
field("wb_quadlets", U32("firelink.wblock.quadlets", "Quadlets", D, nil, 0x000000FF))
field("wb_control", U32("firelink.wblock.control", "Control (to STATUS)", H))
-- Snake node.
field("s_status", U32("firelink.snake.status", "STATUS", H))
field("ss_id", U32("firelink.snake.status.board_id", "Board ID", D, nil, 0x0F000000))
field("ss_wdog", ProtoField.bool("firelink.snake.status.watchdog_timeout", "Watchdog timed out", 32, nil, 0x00800000))
field("ss_fault", U32("firelink.snake.status.amp_fault", "Amplifier faults", H, nil, 0x007F0000))
field("ss_mask", U32("firelink.snake.status.enable_mask", "Enable mask", H, nil, 0x0000FF00))
field("ss_amp", U32("firelink.snake.status.amp_enable", "Amplifier enables", H, nil, 0x000000FF))
field("s_timestamp", U32("firelink.snake.timestamp", "Timestamp (49.152 MHz clocks)", D))
field("s_channel", U8("firelink.snake.channel", "Channel", D))
field("s_pot", U32("firelink.snake.pot", "Potentiometer", D, nil, 0x3FFF0000))
field("s_cur", U32("firelink.snake.current", "Motor current", D, nil, 0x00003FFF))
field("s_enc", U32("firelink.snake.encoder", "Encoder", H))
field("s_period", U32("firelink.snake.period", "Encoder period", H))
field("s_valid", ProtoField.bool("firelink.snake.valid", "Valid", 32, nil, 0x80000000))
field("s_cmd", U32("firelink.snake.command", "Motor command", H, nil, 0x0000FFFF))
field("s_value", U32("firelink.snake.value", "Register value", H))
-- MAHRU modules.
field("m_cmd", U8("firelink.mahru.command", "Command", D, MAHRU_CMD))
field("m_mask", U32("firelink.mahru.modmask", "Module mask", H))
field("m_mod", U8("firelink.mahru.mod_id", "ModID", D))
field("m_magic", U8("firelink.mahru.magic", "Magic", H))
field("m_kind", U8("firelink.mahru.kind", "Module kind", D, MAHRU_KIND, 0xF0))
field("m_fw", U8("firelink.mahru.firmware", "Firmware", D, nil, 0x0F))
field("m_state", U8("firelink.mahru.state", "State", D, MAHRU_STATE, 0xF0))
field("m_phy", U16("firelink.mahru.phy_id", "Physical ID", D, nil, 0xFC00))
field("m_gen", U16("firelink.mahru.generation", "Generation (low 10 bits)", D, nil, 0x03FF))
field("m_seq", U16("firelink.mahru.sequence", "Sequence", D))
field("m_pos", ProtoField.int32("firelink.mahru.position", "Position (urad)", D))
field("m_vel", ProtoField.int32("firelink.mahru.velocity", "Velocity (urad/s)", D))
field("m_acc", ProtoField.int32("firelink.mahru.acceleration", "Acceleration (mrad/s^2)", D))
field("m_cur", ProtoField.int32("firelink.mahru.current", "Current (mA)", D))
field("m_target", ProtoField.int32("firelink.mahru.target", "Target (urad)", D))
field("m_torque", ProtoField.int32("firelink.mahru.torque", "Torque (mNm)", D))
field("m_ticks", U32("firelink.mahru.servo_ticks", "Servo ticks", D))
field("m_flags", U32("firelink.mahru.flags", "Flags", H))
field("m_slot", U8("firelink.mahru.slot", "QWRITE slot", D))
field("m_valid", U8("firelink.mahru.valid", "Slot flags (bit 0 valid)", H))
field("m_force", ProtoField.int32("firelink.mahru.force", "Force (mN)", D))
field("m_ftorque", ProtoField.int32("firelink.mahru.ft_torque", "Torque (mNm)", D))
local MAHRU_PARAMS = {
    { "gear", "Gear ratio" }, { "kp", "kp (Nm/rad)" }, { "ki", "ki (Nm/(rad s))" }, { "kd", "kd (Nm s/rad)" },
    { "position_min", "Position min (rad)" }, { "position_max", "Position max (rad)" }, { "torque_max", "Torque max (Nm)" },
}
for _, p in ipairs(MAHRU_PARAMS) do
    field("m_" .. p[1], ProtoField.float("firelink.mahru." .. p[1], p[2]))
end
field("m_trace", ProtoField.bytes("firelink.mahru.trace", "Trace buffer"))

local fields = {}
for _, f in pairs(F) do
    fields[#fields + 1] = f
end
firelink.fields = fields

local E = {
    crc = ProtoExpert.new("firelink.crc.bad.expert", "Bad CRC", expert.group.CHECKSUM, expert.severity.ERROR),
    truncated = ProtoExpert.new("firelink.truncated", "Truncated", expert.group.MALFORMED, expert.severity.ERROR),
    tcode = ProtoExpert.new("firelink.tcode.unknown", "Unknown tcode", expert.group.PROTOCOL, expert.severity.WARN),
    size = ProtoExpert.new("firelink.size.unexpected", "Unexpected block size", expert.group.PROTOCOL, expert.severity.WARN),
    trailing = ProtoExpert.new("firelink.trailing", "Trailing bytes", expert.group.PROTOCOL, expert.severity.WARN),
    phy = ProtoExpert.new("firelink.phy.bad_check", "PHY packet check quadlet is not the complement", expert.group.CHECKSUM, expert.severity.ERROR),
    ack = ProtoExpert.new("firelink.ack.bad_check", "Ack check nibble is not the complement", expert.group.CHECKSUM, expert.severity.ERROR),
    rcode = ProtoExpert.new("firelink.rcode.error", "Response code is an error", expert.group.RESPONSE_CODE, expert.severity.NOTE),
}
firelink.experts = { E.crc, E.truncated, E.tcode, E.size, E.trailing, E.phy, E.ack, E.rcode }

firelink.prefs.robot = Pref.enum("Robot", 0, "Which robot's address map decodes offsets (auto: from the capture)", {
    { 1, "auto", 0 }, { 2, "dvrk", 1 }, { 3, "snake", 2 }, { 4, "mahru", 3 },
}, false)

---------------------------------------------------------------------------
-- Per-capture state: transactions (request offset for each response) and
-- the robot evidence. Reset when a capture is (re)loaded.

local pending, answered, evidence

local function reset()
    pending = {}
    answered = {}
    evidence = { dvrk = 0, snake = 0, mahru = 0 }
end
reset()
firelink.init = reset

local function robot()
    local p = firelink.prefs.robot
    if p ~= 0 then
        return ROBOTS[p]
    end
    local best = "dvrk"
    for _, name in ipairs(ROBOTS) do
        if evidence[name] > evidence[best] then
            best = name
        end
    end
    return best
end

local RT_BLOCK_QUADLETS = { [12] = true, [28] = true, [32] = true, [52] = true, [60] = true }

-- Evidence from one packet (first pass only). `req` is the request a
-- response answers (nil for requests).
local function note_evidence(tcode, offset, dlen, q3, req)
    if req then
        tcode, offset = tcode, req.offset
    end
    if offset == nil then
        return
    end
    local low = offset % 65536
    if tcode == 0x1 and offset == 18 and dlen == 320 then
        evidence.mahru = evidence.mahru + 1
    elseif tcode == 0x5 and ((offset == 17 and dlen == 32) or (offset == 19 and dlen == 24)) then
        evidence.mahru = evidence.mahru + 1
    elseif tcode == 0x6 and offset == 11 and q3 and bits(q3, 31, 24) == 0x4D then
        evidence.mahru = evidence.mahru + 1
    elseif offset == 0 and ((tcode == 0x5 or tcode == 0x7) and dlen == 92 or tcode == 0x1 and dlen == 28) then
        evidence.snake = evidence.snake + 1
    elseif tcode == 0x6 and offset == 4 and q3 and bits(q3, 31, 8) == 0x534E4B then
        -- A Snake node's version register: "SNK" and the version.
        evidence.snake = evidence.snake + 1
    elseif tcode == 0x6 and offset == 4 and q3 and (q3 == 0x514C4131 or q3 == 0x44514C41 or q3 == 0x64524131) then
        evidence.dvrk = evidence.dvrk + 1
    elseif offset >= STATUS_BROADCAST or (offset < 0x10000 and low >= 0x1000 and low < 0x2000) then
        evidence.dvrk = evidence.dvrk + 1
    elseif offset == 0 and (tcode == 0x5 or tcode == 0x7) and dlen and RT_BLOCK_QUADLETS[dlen / 4] then
        evidence.dvrk = evidence.dvrk + 1
    end
end

---------------------------------------------------------------------------
-- Helpers.

local function hex(v, digits)
    return string.format("0x%0" .. (digits or 1) .. "x", v)
end

-- Whether `len` bytes from `at` are there; expert info when not.
local function need(tvb, at, len, tree, what)
    if at + len <= tvb:len() then
        return true
    end
    tree:add_proto_expert_info(E.truncated, "Truncated: " .. what .. " needs " .. (at + len) .. " bytes, " .. tvb:len() .. " captured")
    return false
end

local function q(tvb, i)
    return tvb(i * 4, 4):uint()
end

---------------------------------------------------------------------------
-- dVRK.

-- Add the fields named by `keys` over the same bytes `r`.
local function add_all(tree, keys, r)
    for _, k in ipairs(keys) do
        tree:add(F[k], r)
    end
end

local STATUS_BITS = { "bs_axes", "bs_id", "bs_wdog", "bs_qdac", "bs_supply", "bs_power", "bs_relay_state",
    "bs_relay_on", "bs_fault", "bs_feedback", "bs_ioexp", "bs_ampfault", "bs_safety", "bs_amp" }
-- The fields of a board register's and an axis register's quadlet (by
-- register offset); the others get the plain value field.
local BOARD_REG_FIELDS = { [3] = { "b_wdog" }, [5] = { "b_temp" }, [10] = { "b_din" } }
local AXIS_REG_FIELDS = {
    [0] = { "a_pot", "a_cur" }, [5] = { "a_enc", "a_enc_raw" }, [6] = { "a_period" },
    [7] = { "a_qtr1" }, [9] = { "a_qtr5" }, [10] = { "a_run" }, [12] = { "a_mstatus" },
}
-- The per-axis sections of the real-time read block, in wire order, as
-- the axis registers they copy.
local SECTIONS_REV4 = { 0, 5 }
local SECTIONS_REV7 = { 0, 5, 6, 7, 9, 10 }
local SECTIONS_REV8 = { 0, 5, 6, 7, 9, 10, 12 }

local function board_status(tvb, at, tree)
    local r = tvb(at, 4)
    add_all(tree:add(F.b_status, r), STATUS_BITS, r)
    return r:uint()
end

local function dac_word(tvb, at, tree, motor)
    local r = tvb(at, 4)
    local t = tree:add(F.a_dac, r)
    t:prepend_text("Motor " .. motor .. " ")
    add_all(t, { "a_dac_valid", "a_dac_mask", "a_dac_en", "a_dac_board", "a_dac_cmd" }, r)
end

local function fourcc(v)
    local s = ""
    for i = 3, 0, -1 do
        local c = bits(v, i * 8 + 7, i * 8)
        s = s .. ((c >= 32 and c < 127) and string.char(c) or ".")
    end
    return s
end

-- Block format of a real-time read block of `n` quadlets with `axes`
-- axes: "rev8", "rev7", "rev4" or nil.
local function read_format(n, axes)
    if n == 4 + 7 * axes then
        return "rev8"
    elseif n == 4 + 6 * axes then
        return "rev7"
    elseif n == 4 + 2 * axes then
        return "rev4"
    end
    return nil
end

local function axes_of(status)
    local a = bits(status, 31, 28)
    return a > 0 and a or 4
end

-- One board's real-time read block: `n` quadlets of tvb from `at`.
local function rt_read_block(tvb, at, n, tree)
    if n < 4 then
        tree:add_proto_expert_info(E.size, "Real-time block of " .. n .. " quadlets")
        return
    end
    tree:add(F.b_timestamp, tvb(at, 4))
    local status = board_status(tvb, at + 4, tree)
    tree:add(F.b_din, tvb(at + 8, 4))
    tree:add(F.b_temp, tvb(at + 12, 4))
    local axes = axes_of(status)
    local fmt = read_format(n, axes)
    if not fmt then
        tree:add_proto_expert_info(E.size, "Real-time block of " .. n .. " quadlets fits no format for " .. axes .. " axes")
        return
    end
    tree:append_text(" (" .. fmt .. ", " .. axes .. " axes)")
    local sections = (fmt == "rev8" and SECTIONS_REV8) or (fmt == "rev7" and SECTIONS_REV7) or SECTIONS_REV4
    for a = 0, axes - 1 do
        local t = tree:add(F.axis, tvb(at + 16 + 4 * a, 4), a + 1)
        for s, reg in ipairs(sections) do
            add_all(t, AXIS_REG_FIELDS[reg], tvb(at + 16 + 4 * ((s - 1) * axes + a), 4))
        end
    end
end

-- A board's write block or a command block (several boards' blocks).
local function rt_write_blocks(tvb, at, n, tree)
    local pos = 0
    local first = q(tvb, at / 4)
    if bits(first, 31, 16) == 0 and bits(first, 7, 0) >= 2 then
        -- Rev 8: each slice starts with its header.
        while pos < n do
            local h = tvb(at + 4 * pos, 4):uint()
            local size = bits(h, 7, 0)
            if size < 2 or pos + size > n or bits(h, 31, 16) ~= 0 then
                tree:add_proto_expert_info(E.size, "Write block header " .. hex(h, 8) .. " at quadlet " .. pos)
                return
            end
            local t = tree:add(firelink, tvb(at + 4 * pos, 4 * size), "Write block, board " .. bits(h, 15, 8))
            t:add(F.b_id, tvb(at + 4 * pos + 2, 1))
            local hr = tvb(at + 4 * pos, 4)
            local ht = t:add(F.wb_header, hr)
            ht:add(F.wb_board, hr)
            ht:add(F.wb_quadlets, hr)
            for m = 1, size - 2 do
                dac_word(tvb, at + 4 * (pos + m), t, m)
            end
            t:add(F.wb_control, tvb(at + 4 * (pos + size - 1), 4))
            pos = pos + size
        end
        return
    end
    -- Rev 7 (4 DAC quadlets and a control quadlet per QLA board) or Rev 4
    -- (4 DAC quadlets); the board ID sits in the DAC quadlets' bits 27:24.
    local size = (n % 5 == 0) and 5 or ((n % 4 == 0) and 4 or nil)
    if not size then
        tree:add_proto_expert_info(E.size, "Write block of " .. n .. " quadlets fits no format")
        return
    end
    while pos < n do
        local id = bits(q(tvb, at / 4 + pos), 27, 24)
        local t = tree:add(firelink, tvb(at + 4 * pos, 4 * size), "Write block, board " .. id .. (size == 5 and " (Rev 7)" or " (Rev 4)"))
        t:add(F.b_id, id)
        for m = 1, 4 do
            dac_word(tvb, at + 4 * (pos + m - 1), t, m)
        end
        if size == 5 then
            t:add(F.wb_control, tvb(at + 4 * (pos + 4), 4))
        end
        pos = pos + size
    end
end

-- The hub block read from 0x1000: the boards' entries and the timing quadlet.
local function hub_block(tvb, at, n, tree)
    if n < 3 then
        tree:add_proto_expert_info(E.size, "Hub block of " .. n .. " quadlets")
        return
    end
    local h0 = q(tvb, at / 4)
    local axes = axes_of(q(tvb, at / 4 + 2))
    local rev8 = bits(h0, 31, 24) == 5 + 7 * axes
    local block
    if not rev8 then
        -- Rev 7: seq<<16 | time and 4 + 6 x axes quadlets, a timing quadlet
        -- at the end; Rev 4: 4 + 2 x axes and no timing quadlet.
        if (n - 1) % (5 + 6 * axes) == 0 then
            block = 4 + 6 * axes
        elseif n % (5 + 2 * axes) == 0 then
            block = 4 + 2 * axes
        else
            tree:add_proto_expert_info(E.size, "Hub block of " .. n .. " quadlets fits no format")
            return
        end
    end
    local pos = 0
    while pos < n do
        if n - pos == 1 then
            local r = tvb(at + 4 * pos, 4)
            local t = tree:add(firelink, r, "Hub timing")
            t:add(F.hub_read_start, r)
            t:add(F.hub_now, r)
            return
        end
        local hr = tvb(at + 4 * pos, 4)
        local size = rev8 and bits(hr:uint(), 31, 24) or block + 1
        if size < 5 or pos + size > n then
            tree:add_proto_expert_info(E.size, "Hub entry of " .. size .. " quadlets at quadlet " .. pos)
            return
        end
        local empty = not rev8
        for i = pos, pos + size - 1 do
            empty = empty and q(tvb, at / 4 + i) == 0
        end
        if empty then
            -- Seed 000's firmware keeps a fixed slot per board ID: zeros
            -- where no board broadcast.
            tree:add(firelink, tvb(at + 4 * pos, 4 * size), "Empty hub slot")
            pos = pos + size
            goto continue
        end
        local id = bits(q(tvb, at / 4 + pos + 2), 27, 24)
        local t = tree:add(F.hub_board, tvb(at + 4 * pos, 4 * size))
        t:set_text("Board " .. id)
        t:add(F.b_id, id)
        if rev8 then
            t:add(F.hub8_size, hr)
            t:add(F.hub8_seq, hr)
            t:add(F.hub8_err, hr)
            t:add(F.hub8_time, hr)
        else
            t:add(F.hub7_seq, hr)
            t:add(F.hub7_time, hr)
        end
        rt_read_block(tvb, at + 4 * pos + 4, size - 1, t)
        pos = pos + size
        ::continue::
    end
end

-- A name for a dVRK offset: space, register.
local function dvrk_name(offset)
    if offset >= STATUS_BROADCAST and offset < STATUS_BROADCAST + 16 * 0x20 then
        return "status broadcast", "broadcast"
    elseif offset == COMMAND_SNOOP then
        return "command block (snooped by node 0)", "broadcast"
    end
    local low = offset % 65536
    local space = math.floor(low / 4096)
    local sname = SPACE[space] or ("space " .. space)
    if space == 0 then
        local channel, reg = bits(low, 7, 4), bits(low, 3, 0)
        if bits(low, 11, 8) ~= 0 then
            return "unmapped " .. hex(low, 4), sname
        elseif channel == 0 then
            return BOARD_REG[reg] or ("board register " .. reg), sname
        else
            return "axis " .. channel .. " " .. (AXIS_REG[reg] or ("register " .. reg)), sname
        end
    elseif space == 1 then
        if low == 0x1800 then
            return "hub query", sname
        elseif low == 0x1802 then
            return "hub quadlets written", sname
        elseif low < 0x1800 then
            return "hub memory", sname
        end
        return "hub " .. hex(low, 4), sname
    end
    return sname .. " " .. hex(low % 4096, 3), sname
end

-- The meaning of a quadlet at a dVRK register (read answer or write).
local function dvrk_quadlet(offset, write, tvbr, tree)
    local low = offset % 65536
    local v = tvbr:uint()
    if low == 0x1800 then
        tree:add(F.q_seq, tvbr)
        tree:add(F.q_mask, tvbr)
        return " seq=" .. bits(v, 31, 16) .. " mask=" .. hex(bits(v, 15, 0), 4)
    end
    if offset ~= low or bits(low, 15, 8) ~= 0 then
        return ""
    end
    local channel, reg = bits(low, 7, 4), bits(low, 3, 0)
    if channel == 0 then
        if reg == 0 then
            if write then
                tree:add(F.b_status_write, tvbr)
                return ""
            end
            add_all(tree:add(F.b_status, tvbr), STATUS_BITS, tvbr)
            return " board " .. bits(v, 27, 24)
        elseif reg == 4 then
            tree:add(F.b_hw, tvbr, fourcc(v))
            return " " .. fourcc(v)
        elseif reg == 7 then
            tree:add(F.b_fw, tvbr)
            return " Rev " .. v
        elseif reg == 11 then
            tree:add_le(F.b_ip, tvbr)
        else
            add_all(tree, BOARD_REG_FIELDS[reg] or { "b_reg" }, tvbr)
        end
        return ""
    end
    local t = tree:add(F.axis, channel)
    if reg == 1 and write then
        dac_word(tvbr:tvb(), 0, t, channel)
    else
        add_all(t, AXIS_REG_FIELDS[reg] or { "a_reg" }, tvbr)
    end
    return ""
end

local function dvrk_block(offset, tcode, dst_phy, data, tree)
    local n = math.floor(data:len() / 4)
    local low = offset % 65536
    if offset >= STATUS_BROADCAST and offset < STATUS_BROADCAST + 16 * 0x20 then
        if n < 1 then
            return
        end
        local hr = data(0, 4)
        tree:add(F.sb_seq, hr)
        tree:add(F.sb_size, hr)
        local id = n >= 3 and bits(q(data, 2), 27, 24) or nil
        local t = tree:add(firelink, data(0, 4 * n), "Status broadcast" .. (id and (", board " .. id) or ""))
        if id then
            t:add(F.b_id, id)
        end
        rt_read_block(data, 4, n - 1, t)
        return
    end
    if offset == COMMAND_SNOOP or (offset == 0 and tcode == 0x1) then
        rt_write_blocks(data, 0, n, tree)
        return
    end
    if offset == 0 and tcode == 0x7 then
        local t = tree:add(firelink, data(0, 4 * n), "Real-time read block")
        rt_read_block(data, 0, n, t)
        return
    end
    if low == 0x1000 and offset == low and tcode == 0x7 then
        local t = tree:add(firelink, data(0, 4 * n), "Hub block")
        hub_block(data, 0, n, t)
    end
end

---------------------------------------------------------------------------
-- Snake node (seed 001).

local function snake_name(offset)
    if offset > 0xFF then
        return "not a Snake address " .. hex(offset), "Snake"
    end
    local channel, dev = bits(offset, 7, 4), bits(offset, 3, 0)
    if channel == 0 then
        return SNAKE_GLOBAL[dev] or ("global " .. dev), "Snake"
    elseif channel <= 7 then
        return "channel " .. channel .. " " .. (SNAKE_DEVICE[dev] or ("device " .. dev)), "Snake"
    end
    return "not a Snake address " .. hex(offset), "Snake"
end

local function snake_status(tvbr, tree)
    add_all(tree:add(F.s_status, tvbr), { "ss_id", "ss_wdog", "ss_fault", "ss_mask", "ss_amp" }, tvbr)
end

local function snake_quadlet(offset, write, tvbr, tree)
    if offset == 0 and not write then
        snake_status(tvbr, tree)
        return " board " .. bits(tvbr:uint(), 27, 24)
    end
    if offset <= 0xFF and bits(offset, 7, 4) >= 1 and bits(offset, 7, 4) <= 7 then
        local t = tree:add(F.s_channel, bits(offset, 7, 4))
        if bits(offset, 3, 0) == 0 then
            t:add(F.s_pot, tvbr)
            t:add(F.s_cur, tvbr)
        else
            t:add(F.s_value, tvbr)
        end
    else
        tree:add(F.s_value, tvbr)
    end
    return ""
end

local function snake_block(offset, tcode, data, tree)
    if offset ~= 0 then
        return
    end
    local n = math.floor(data:len() / 4)
    if tcode == 0x7 then
        local t = tree:add(firelink, data(0, 4 * n), "Snake block read")
        if n ~= 23 then
            t:add_proto_expert_info(E.size, "Snake block read of " .. n .. " quadlets (23 expected)")
            return
        end
        snake_status(data(0, 4), t)
        t:add(F.s_timestamp, data(4, 4))
        for c = 1, 7 do
            local ct = t:add(F.s_channel, data(4 * (1 + c), 4), c)
            ct:add(F.s_pot, data(4 * (1 + c), 4))
            ct:add(F.s_cur, data(4 * (1 + c), 4))
            ct:add(F.s_enc, data(4 * (8 + c), 4))
            ct:add(F.s_period, data(4 * (15 + c), 4))
        end
    elseif tcode == 0x1 then
        local t = tree:add(firelink, data(0, 4 * n), "Snake block write")
        if n ~= 7 then
            t:add_proto_expert_info(E.size, "Snake block write of " .. n .. " quadlets (7 expected)")
            return
        end
        for c = 1, 7 do
            local r = data(4 * (c - 1), 4)
            local ct = t:add(F.s_channel, r, c)
            ct:add(F.s_valid, r)
            ct:add(F.s_cmd, r)
        end
    end
end

---------------------------------------------------------------------------
-- MAHRU modules (seed 002).

local function mahru_name(offset)
    if offset < 0x100 then
        return MAHRU_CMD[offset] or ("command " .. offset), "MAHRU command"
    elseif offset == MAHRU_TRACE then
        return "trace buffer", "MAHRU"
    end
    return "not a MAHRU command " .. hex(offset), "MAHRU"
end

local function mahru_quadlet(offset, write, tvbr, tree)
    local v = tvbr:uint()
    if write and (offset == 0 or (offset >= 14 and offset <= 16)) then
        tree:add(F.m_mask, tvbr)
        return " mask=" .. hex(v, 8)
    elseif not write and offset == 11 then
        local t = tree:add(firelink, tvbr, "Identity")
        t:add(F.m_magic, tvbr(0, 1))
        t:add(F.m_kind, tvbr(1, 1))
        t:add(F.m_fw, tvbr(1, 1))
        t:add(F.m_mod, tvbr(3, 1))
        return " ModID " .. bits(v, 7, 0)
    elseif not write and offset == 12 then
        local t = tree:add(firelink, tvbr, "IdCheck")
        t:add(F.m_mod, tvbr(0, 1))
        t:add(F.m_state, tvbr(1, 1))
        t:add(F.m_phy, tvbr(2, 2))
        t:add(F.m_gen, tvbr(2, 2))
        return " ModID " .. bits(v, 31, 24)
    end
    return ""
end

local function mahru_block(offset, tcode, data, tree)
    local len = data:len()
    if tcode == 0x7 and offset == 17 then
        if len ~= 32 then
            tree:add_proto_expert_info(E.size, "QREAD answer of " .. len .. " bytes (32 expected)")
            return
        end
        local t = tree:add(firelink, data(0, 32), "Joint block, ModID " .. data(0, 1):uint())
        t:add(F.m_mod, data(0, 1))
        t:add(F.m_state, data(1, 1))
        t:add(F.m_seq, data(2, 2))
        t:add(F.m_pos, data(4, 4))
        t:add(F.m_vel, data(8, 4))
        t:add(F.m_cur, data(12, 4))
        t:add(F.m_target, data(16, 4))
        t:add(F.m_torque, data(20, 4))
        t:add(F.m_ticks, data(24, 4))
        t:add(F.m_flags, data(28, 4))
    elseif tcode == 0x7 and offset == 19 then
        if len ~= 24 then
            tree:add_proto_expert_info(E.size, "FTREAD answer of " .. len .. " bytes (24 expected)")
            return
        end
        local t = tree:add(firelink, data(0, 24), "Force/torque block")
        for i = 0, 2 do
            t:add(F.m_force, data(4 * i, 4)):append_text(" (" .. ("xyz"):sub(i + 1, i + 1) .. ")")
        end
        for i = 0, 2 do
            t:add(F.m_ftorque, data(12 + 4 * i, 4)):append_text(" (" .. ("xyz"):sub(i + 1, i + 1) .. ")")
        end
    elseif tcode == 0x1 and offset == 18 then
        if len ~= 320 then
            tree:add_proto_expert_info(E.size, "QWRITE of " .. len .. " bytes (320 expected)")
        end
        for s = 0, math.floor(len / 32) - 1 do
            local r = data(32 * s, 32)
            local t = tree:add(F.m_slot, r, s)
            t:append_text(", ModID " .. r(0, 1):uint() .. ((r(1, 1):uint() % 2 == 1) and "" or " (not valid)"))
            t:add(F.m_mod, r(0, 1))
            t:add(F.m_valid, r(1, 1))
            t:add(F.m_seq, r(2, 2))
            t:add(F.m_pos, r(4, 4))
            t:add(F.m_vel, r(8, 4))
            t:add(F.m_acc, r(12, 4))
            t:add(F.m_torque, r(16, 4))
        end
    elseif tcode == 0x1 and offset == 13 then
        if len % 32 ~= 0 then
            tree:add_proto_expert_info(E.size, "PARAMETER of " .. len .. " bytes (whole 32-byte records expected)")
        end
        for s = 0, math.floor(len / 32) - 1 do
            local r = data(32 * s, 32)
            local t = tree:add(firelink, r, "Parameter record, ModID " .. r(0, 1):uint())
            t:add(F.m_mod, r(0, 1))
            for i, p in ipairs(MAHRU_PARAMS) do
                t:add(F["m_" .. p[1]], r(4 * i, 4))
            end
        end
    elseif offset == MAHRU_TRACE then
        tree:add(F.m_trace, data)
    end
end

---------------------------------------------------------------------------
-- The 1394 packet.

local function crc_check(tvb, at, len, crc_at, tree, f_crc, f_status, what, zero_allowed)
    local stored = tvb(crc_at, 4):uint()
    local computed = crc1394(tvb, at, len)
    local t = tree:add(f_crc, tvb(crc_at, 4))
    local status
    if stored == computed then
        status = 0
        t:append_text(" [good]")
    elseif stored == 0 and zero_allowed then
        status = 2
        t:append_text(" [not computed]")
    else
        status = 1
        t:append_text(" [bad: computed " .. hex(computed, 8) .. "]")
        t:add(F.crc_computed, computed)
        t:add(F.crc_bad, true)
        t:add_proto_expert_info(E.crc, "Bad " .. what .. " CRC: " .. hex(stored, 8) .. ", computed " .. hex(computed, 8))
    end
    t:add(f_status, status)
    return status
end

local function phy_packet(tvb, tree)
    local r = tvb(4, 4)
    local v = r:uint()
    local t = tree:add(F.phy_quadlet, r)
    local kind = bits(v, 31, 30)
    t:add(F.phy_kind, r)
    t:add(F.phy_id, r)
    local info = PHY_KIND[kind] .. " phy=" .. bits(v, 29, 24)
    if kind == 0 then
        t:add(F.phy_root, r)
        t:add(F.phy_set_gap, r)
        t:add(F.phy_gap, r)
        info = info .. " gap_count=" .. bits(v, 21, 16)
    elseif kind == 2 then
        add_all(t, { "phy_link", "phy_gap", "phy_speed", "phy_contender", "phy_ports", "phy_initiated", "phy_more" }, r)
    end
    local c = tree:add(F.phy_check, tvb(8, 4))
    if bxor(v, tvb(8, 4):uint()) ~= 0xFFFFFFFF then
        c:add_proto_expert_info(E.phy)
        c:add(F.crc_bad, true)
    end
    return info
end

-- Dissect one 1394 packet in `tvb`; `bridge_response`: CRC fields of 0
-- are "not computed". Returns the bytes the packet takes and a summary.
local function packet(tvb, pinfo, tree, bridge_response)
    local len = tvb:len()
    if len < 4 then
        tree:add_proto_expert_info(E.truncated, "Truncated: " .. len .. " bytes, a 1394 packet header starts with 4")
        return len, "truncated"
    end
    local q0r = tvb(0, 4)
    local tcode = bits(q0r:uint(), 7, 4)
    local hlen = HEADER_LEN[tcode]
    local t = tree:add(firelink, tvb(0, len), "IEEE 1394 packet: " .. (TCODE[tcode] or ("tcode " .. hex(tcode))))
    t:add(F.tcode, tvb(3, 1))
    if not hlen then
        t:add_proto_expert_info(E.tcode, "Unknown tcode " .. hex(tcode) .. ": the rest is not decoded")
        t:add(F.data, tvb(4))
        return len, "tcode " .. hex(tcode)
    end
    if tcode == 0xE then
        if not need(tvb, 0, 12, t, "PHY packet") then
            return len, "PHY packet (truncated)"
        end
        return 12, phy_packet(tvb, t)
    end
    if tcode == 0xA then
        t:add(F.data_length, tvb(0, 2))
        t:add(F.stream_channel, tvb(2, 1))
    else
        t:add(F.dst, tvb(0, 2))
        t:add(F.dst_bus, tvb(0, 2))
        t:add(F.dst_phy, tvb(0, 2))
        t:add(F.tlabel, tvb(2, 2))
        t:add(F.retry, tvb(2, 2))
    end
    t:add(F.priority, tvb(3, 1))
    if not need(tvb, 0, hlen + 4, t, TCODE[tcode] .. " header") then
        return len, TCODE[tcode] .. " (truncated)"
    end
    local q0 = q0r:uint()
    local dst, tl = bits(q0, 31, 16), bits(q0, 15, 10)
    local src, offset, rcode, dlen, q3
    local summary = TCODE[tcode]
    if tcode ~= 0xA then
        src = tvb(4, 2):uint()
        t:add(F.src, tvb(4, 2))
        t:add(F.src_bus, tvb(4, 2))
        t:add(F.src_phy, tvb(4, 2))
        summary = summary .. " " .. hex(src, 4) .. "->" .. hex(dst, 4) .. " tl=" .. tl
    end
    if IS_REQUEST[tcode] then
        offset = tvb(6, 2):uint() * TWO32 + tvb(8, 4):uint()
        t:add(F.offset, tvb(6, 6), UInt64(tvb(8, 4):uint(), tvb(6, 2):uint()))
        summary = summary .. " offset=" .. string.format("0x%012x", offset)
    elseif IS_RESPONSE[tcode] then
        rcode = bits(tvb(6, 1):uint(), 7, 4)
        t:add(F.rcode, tvb(6, 1))
        if rcode ~= 0 then
            t:add_proto_expert_info(E.rcode, "rcode " .. (RCODE[rcode] or rcode))
        end
        summary = summary .. " " .. (RCODE[rcode] or ("rcode " .. rcode))
    end
    if hlen == 16 then
        if HAS_BLOCK_LENGTH[tcode] then
            dlen = tvb(12, 2):uint()
            t:add(F.data_length, tvb(12, 2))
            t:add(F.ext_tcode, tvb(14, 2))
            summary = summary .. " len=" .. dlen
        elseif tcode == 0x8 then
            t:add(F.cycle_time, tvb(12, 4))
        else
            q3 = tvb(12, 4):uint()
            t:add(F.quadlet, tvb(12, 4))
            summary = summary .. " data=" .. hex(q3, 8)
        end
    elseif tcode == 0xA then
        dlen = tvb(0, 2):uint()
    end
    local bad = crc_check(tvb, 0, hlen, hlen, t, F.header_crc, F.header_crc_status, "header", bridge_response) == 1
    local total = hlen + 4
    local data
    if HAS_DATA[tcode] and dlen and dlen > 0 then
        local padded = math.floor((dlen + 3) / 4) * 4
        if not need(tvb, hlen + 4, padded + 4, t, dlen .. " bytes of data and the data CRC") then
            if tvb:len() > hlen + 4 then
                t:add(F.data, tvb(hlen + 4))
            end
            return len, summary .. " (truncated)"
        end
        data = tvb(hlen + 4, dlen):tvb()
        t:add(F.data, tvb(hlen + 4, dlen))
        bad = crc_check(tvb, hlen + 4, padded, hlen + 4 + padded, t, F.data_crc, F.data_crc_status, "data", bridge_response) == 1 or bad
        total = hlen + 4 + padded + 4
    end
    if bad then
        summary = summary .. " [BAD CRC]"
    end

    -- Transactions: which request a response answers.
    local req
    if IS_REQUEST[tcode] and tcode ~= 0x8 and not pinfo.visited then
        local info = { offset = offset, tcode = tcode, frame = pinfo.number }
        pending[src .. ":" .. dst .. ":" .. tl] = info
        pending[src .. ":*:" .. tl] = info
    elseif IS_RESPONSE[tcode] then
        if not pinfo.visited then
            answered[pinfo.number] = pending[dst .. ":" .. src .. ":" .. tl] or pending[dst .. ":*:" .. tl]
        end
        req = answered[pinfo.number]
        if req then
            t:add(F.request_in, req.frame)
            t:add(F.response_to, UInt64(req.offset % TWO32, math.floor(req.offset / TWO32)))
        end
    end
    if not pinfo.visited then
        note_evidence(tcode, offset, dlen, q3, req)
    end

    -- The meaning of the offset and the data, by robot.
    local at = offset or (req and req.offset)
    if at then
        local r = robot()
        t:add(F.robot, r)
        local name, space
        local block = tcode == 0x1 or tcode == 0x5 or tcode == 0x7
        if r == "snake" then
            name, space = snake_name(at)
            if at == 0 and block then
                name = (tcode == 0x1) and "block write" or "block read"
            end
        elseif r == "mahru" then
            name, space = mahru_name(at)
            if at < 0x100 then
                t:add(F.m_cmd, at)
            end
        else
            name, space = dvrk_name(at)
            if at == 0 and block then
                name = bits(dst, 5, 0) == 63 and "command block"
                    or ((tcode == 0x1) and "real-time write block" or "real-time read block")
            end
        end
        t:add(F.space, space)
        t:add(F.register, name)
        summary = summary .. " [" .. name .. "]"
        local write = tcode == 0x0
        if q3 and (tcode == 0x0 or tcode == 0x6) then
            local qr = tvb(12, 4)
            if r == "snake" then
                summary = summary .. snake_quadlet(at, write, qr, t)
            elseif r == "mahru" then
                summary = summary .. mahru_quadlet(at, write, qr, t)
            else
                summary = summary .. dvrk_quadlet(at, write, qr, t)
            end
        elseif data and (tcode == 0x1 or tcode == 0x7) then
            if r == "snake" then
                snake_block(at, tcode, data, t)
            elseif r == "mahru" then
                mahru_block(at, tcode, data, t)
            else
                dvrk_block(at, tcode, bits(dst, 5, 0), data, t)
            end
        end
    end
    return total, summary
end

local function ack(tvb, tree)
    local r = tvb(0, 1)
    local v = r:uint()
    local code = bits(v, 7, 4)
    local t = tree:add(F.ack, r)
    if bits(v, 3, 0) + code ~= 15 then
        t:add_proto_expert_info(E.ack)
        t:add(F.crc_bad, true)
    end
    return "ack " .. (ACK[code] or hex(code))
end

---------------------------------------------------------------------------
-- The two carriers.

local function is_firelink_address(addr)
    return tostring(addr):find("^127%.13%.94%.") ~= nil
end

function firelink.dissector(tvb, pinfo, tree)
    local len = tvb:len()
    if len == 0 then
        return 0
    end
    pinfo.cols.protocol = "Firelink"
    local root = tree:add(firelink, tvb(), "Firelink IEEE 1394")
    local info
    if is_firelink_address(pinfo.src) and is_firelink_address(pinfo.dst) then
        local kind = "bus"
        if pinfo.src_port == 1395 then
            kind = "host sent"
        elseif pinfo.dst_port == 1395 then
            kind = "host received"
        end
        root:add(F.kind, kind)
        if len == 1 then
            info = ack(tvb, root)
        else
            local used
            used, info = packet(tvb, pinfo, root, false)
            if used < len then
                root:add_proto_expert_info(E.trailing, (len - used) .. " bytes after the packet")
            end
        end
    elseif len % 4 == 2 then
        -- Bridge, host -> board: the control word, then the packet.
        root:add(F.kind, "bridge request")
        local r = tvb(0, 2)
        local ct = root:add(F.control, r)
        ct:add(F.control_nf, r)
        ct:add(F.control_gen, r)
        local used
        used, info = packet(tvb(2):tvb(), pinfo, root, false)
        if used < len - 2 then
            root:add_proto_expert_info(E.trailing, (len - 2 - used) .. " bytes after the packet")
        end
        info = "bridge gen " .. bits(r:uint(), 7, 0) .. (bits(r:uint(), 8, 8) == 1 and " no-forward " or " ") .. info
    else
        -- Bridge, board -> host: the response, then 8 bytes of extra data.
        root:add(F.kind, "bridge response")
        local used
        used, info = packet(tvb, pinfo, root, true)
        local rest = len - used
        if rest > 0 then
            local xr = tvb(used, rest)
            local xt = root:add(F.extra, xr)
            if rest < 8 then
                xt:add_proto_expert_info(E.truncated, "Truncated: bridge extra data is 8 bytes, " .. rest .. " here")
            else
                local fr = tvb(used, 1)
                add_all(xt:add(F.x_flags, fr), { "x_reset", "x_dropped", "x_internal", "x_summary", "x_nf", "x_port" }, fr)
                xt:add(F.x_gen, tvb(used + 1, 1))
                xt:add(F.x_invalid, tvb(used + 2, 1))
                xt:add(F.x_errors, tvb(used + 3, 1))
                xt:add(F.x_rx, tvb(used + 4, 2))
                xt:add(F.x_total, tvb(used + 6, 2))
                if rest > 8 then
                    root:add_proto_expert_info(E.trailing, (rest - 8) .. " bytes after the extra data")
                end
                info = info .. " [board gen " .. tvb(used + 1, 1):uint() .. "]"
            end
        elseif used == len and len >= 4 then
            root:add_proto_expert_info(E.truncated, "Truncated: no bridge extra data")
        end
    end
    pinfo.cols.info = info
    return len
end

local udp = DissectorTable.get("udp.port")
udp:add(1394, firelink)
udp:add(1395, firelink)
