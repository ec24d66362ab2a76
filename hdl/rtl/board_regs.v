// board_regs: the QLA1 board's register file at firmware Rev 8
// (shared/spec/fpga-board.md, sections 1-3).
//
// Main space, address 0x00CO: channel C = 0 board registers, 1..4 axes;
// offset O. Reads take a clock (rd_addr -> rd_data, two ports); a read of
// ENC_POSITION (port a) latches the encoder overflow flag when the count is out of
// range (rd_strobe). Writes arrive one quadlet per clock with their time.
// The sensors (ADC, encoder counter and velocity words, switches,
// temperatures) are the QLA's inputs; the board's state words (STATUS,
// DIGITAL_IN, per-axis words) are what the real-time block reads.
// PHY_CTRL requests reach the PHY through the PHY-link interface; the
// answer of a read lands in PHY_DATA.
`default_nettype none

module board_regs #(
    parameter [3:0]  BOARD_ID   = 4'd0,
    parameter [31:0] HW_VERSION = 32'h514C_4131,  // "QLA1"
    parameter [31:0] FW_VERSION = 32'd8,
    // FPGA V2 register 12 with no KSZ8851 traffic: present (31), KSZ
    // initialised (29), UDP mode (20), KSZ idle (18), link down (19 = 0),
    // no register read yet (15:0): what the software board answers.
    parameter [31:0] ETH_STATUS = 32'hA014_0000,
    parameter        HAS_ETHERNET = 1'b1
) (
    input  wire         clk,
    input  wire         rst,
    input  wire [31:0]  now,
    // Write port.
    input  wire         wr_en,
    input  wire [15:0]  wr_addr,
    input  wire [31:0]  wr_data,
    input  wire [31:0]  wr_time,
    // Read ports (data one clock after the address).
    input  wire [15:0]  rd_addr,
    input  wire         rd_strobe,
    output wire [31:0]  rd_data,
    input  wire [15:0]  rd_addr_b,
    output wire [31:0]  rd_data_b,
    input  wire         rt_sample,       // the real-time block was sampled
    // Watchdog (write refresh is the caller's).
    input  wire         watchdog_fire,
    input  wire         watchdog_timed_out,
    input  wire [15:0]  watchdog_period,
    output wire         watchdog_set,
    output wire [15:0]  watchdog_value,
    output wire         watchdog_clear,
    output wire         reboot,          // STATUS 0x00300000 written
    // PHY register access.
    output reg          phy_req_valid,
    input  wire         phy_req_ready,
    output reg          phy_req_write,
    output reg  [3:0]   phy_req_addr,
    output reg  [7:0]   phy_req_data,
    input  wire         phy_rd_valid,
    input  wire [3:0]   phy_rd_addr,
    input  wire [7:0]   phy_rd_data,
    // QLA inputs (4 axes).
    input  wire [127:0] adc,             // per axis: pot 31:16, current 15:0
    input  wire [127:0] enc_raw,         // per axis: signed raw count
    input  wire [127:0] enc_period,
    input  wire [127:0] enc_qtr1,
    input  wire [127:0] enc_qtr5,
    input  wire [127:0] enc_run,
    input  wire [3:0]   enc_a, enc_b, enc_index,
    input  wire [3:0]   neg_limit, pos_limit, home,
    input  wire [15:0]  temperature,
    input  wire         supply_present,
    input  wire         supply_good,
    // QLA outputs.
    output wire         power_enable,
    output wire         relay_on,
    output wire [3:0]   amp_enable,
    output wire [63:0]  dac_out,         // effective commands, 16 per axis
    output wire [7:0]   dout
);
    localparam [31:0] ENC_NEUTRAL = 32'h0080_0000;

    // State words (also read as the real-time block).
    wire [31:0]  status_word, din_word, temp_word;
    wire [127:0] adc_word, pos_word, mstat_word;

    // ---- decode ---------------------------------------------------------
    wire        wr_main  = (wr_addr[15:8] == 8'h00);
    wire [3:0]  wr_chan  = wr_addr[7:4];
    wire [3:0]  wr_reg   = wr_addr[3:0];
    wire        wr_board = wr_en && wr_main && wr_chan == 4'd0;
    wire        wr_axis  = wr_en && wr_main && wr_chan >= 4'd1 && wr_chan <= 4'd4;
    wire [1:0]  wr_ax    = wr_chan[1:0] - 2'd1;

    // ---- storage --------------------------------------------------------
    reg [31:0] phy_ctrl;
    reg [15:0] phy_data;         // host-writable (BoardRegs.v l.94)
    reg        wdog_led;         // WATCHDOG bit 31, stored (BoardRegs.v l.79)
    reg        phy_read_pending;
    reg [3:0]  phy_read_reg;
    reg [7:0]  dout_r;
    reg [31:0] ip_addr;
    reg [15:0] dac_cmd   [0:3];
    reg [31:0] preload   [0:3];
    reg [32:0] offset    [0:3];   // count = raw + offset
    reg [3:0]  overflow;
    reg [7:0]  en_delay  [0:3];
    reg [14:0] cur_limit [0:3];   // MOTOR_CONFIG 14:0 (bit 15 always 0)
    reg [3:0]  no_safety;         // MOTOR_CONFIG bit 31 per axis
    reg [3:0]  force_dis;         // MOTOR_CONFIG bit 30 per axis
    reg [3:0]  ctrl_mode [0:3];   // control mode of the last command

    // ---- STATUS and DAC writes go to board_power -------------------------
    wire status_wr = wr_board && wr_reg == 4'd0;
    assign reboot  = status_wr && wr_data[21:20] == 2'b11;
    wire dac_wr    = wr_axis && wr_reg == 4'd1;
    reg  [3:0] amp_req_valid, amp_req_value;
    always @* begin
        amp_req_valid = 4'd0;
        amp_req_value = 4'd0;
        if (dac_wr && wr_data[29]) begin
            amp_req_valid[wr_ax] = 1'b1;
            amp_req_value[wr_ax] = wr_data[28];
        end
    end

    // The command reaches the DAC as written: MOTOR_CONFIG's current
    // limit is checked by the firmware only in voltage control, which is
    // not modelled (MotorChannelQLA.v). A valid command is taken with its
    // control mode (bits 27:24) when the mode is 0 (current) or 1 (voltage;
    // the QLA 1.5 has an I/O expander) (l.180-191).
    wire        mcfg_wr  = wr_axis && wr_reg == 4'd11;
    wire        mode_ok  = wr_data[27:25] == 3'd0;
    wire        cmd_wr   = dac_wr && wr_data[31] && mode_ok;
    wire [63:0] measured;
    wire [3:0]  cur_ctrl;         // current control (mode other than 1)
    genvar g;
    generate
        for (g = 0; g < 4; g = g + 1) begin : cmd
            assign dac_out[16*g +: 16]  = dac_cmd[g];
            assign measured[16*g +: 16] = adc[32*g +: 16];
            assign cur_ctrl[g]          = ctrl_mode[g] != 4'd1;
        end
    endgenerate

    wire       power_enabled, relay, supply_fault;
    wire [3:0] requested, amp_on, safety_disabled;
    board_power #(.AXES(4)) power (
        .clk(clk), .rst(rst), .now(now),
        .cmd_valid(status_wr && !reboot), .cmd_time(wr_time), .cmd_word(wr_data),
        .amp_req_valid(amp_req_valid), .amp_req_value(amp_req_value),
        .amp_req_time(wr_time), .watchdog_fire(watchdog_fire), .reboot(reboot),
        .enable_delay({en_delay[3], en_delay[2], en_delay[1], en_delay[0]}),
        .delay_written({4{mcfg_wr && wr_data[25]}} & (4'd1 << wr_ax)),
        .measured(measured), .command(dac_out),
        .check_enable(~no_safety & cur_ctrl),
        .supply_present(supply_present), .supply_good(supply_good),
        .power_enabled(power_enabled), .relay(relay), .supply_fault(supply_fault),
        .requested(requested), .amp_on(amp_on), .safety_disabled(safety_disabled),
        .clear_watchdog(watchdog_clear));

    assign watchdog_set   = wr_board && wr_reg == 4'd3;
    assign watchdog_value = wr_data[15:0];
    assign power_enable   = power_enabled;
    assign relay_on       = relay;
    assign amp_enable     = amp_on;
    assign dout           = dout_r;

    // ---- state words -----------------------------------------------------
    // Bits 21:20: the digital-output check is done and the outputs are
    // the bidirectional kind (QLA 1.4+), as the software board reports;
    // the check itself is not modelled here.
    assign status_word = {4'd4, BOARD_ID, watchdog_timed_out, 1'b1, 2'b11,
                          supply_good, power_enabled, relay, relay,
                          supply_fault, relay, 1'b0, 1'b1,
                          4'd0,                 // Rev 8: no amp fault field
                          safety_disabled, requested};
    assign din_word = {supply_fault, 3'd0, enc_a, enc_b, enc_index, dout_r[3:0],
                       neg_limit, pos_limit, home};
    assign temp_word = {16'd0, temperature};

    generate
        for (g = 0; g < 4; g = g + 1) begin : words
            // The count, registered: a sensor reaches the words one clock
            // after it changes (the QLA's inputs are registers too).
            reg  [32:0] count;
            always @(posedge clk)
                count <= {enc_raw[32*g+31], enc_raw[32*g +: 32]} + offset[g];
            wire        out_of_range = count[32] || (count[31:24] != 8'd0);
            assign adc_word[32*g +: 32] = adc[32*g +: 32];
            assign pos_word[32*g +: 32] = {1'b0, enc_index[g], enc_b[g], enc_a[g],
                                           3'd0, overflow[g] | out_of_range,
                                           count[23:0]};
            // MOTOR_STATUS (MotorChannelQLA.v l.172): control mode 27:24,
            // current control 20.
            assign mstat_word[32*g +: 32] = {2'b00, amp_on[g], requested[g],
                                             ctrl_mode[g], 3'd0, cur_ctrl[g], 2'd0,
                                             safety_disabled[g], 1'b0,
                                             dac_cmd[g]};
        end
    endgenerate

    // ---- read ports ----------------------------------------------------------
    // Two read ports (a: transactions, b: the status-broadcast snapshot),
    // each over two registers: the word of every channel (board, axes 1-4)
    // at the address's offset, then the channel's word. Data follows the
    // address by one clock; it comes from registers.
    function [31:0] board_word(input [3:0] r);
        case (r)
            4'd0:  board_word = status_word;
            4'd1:  board_word = phy_ctrl;
            4'd2:  board_word = {16'd0, phy_data};
            4'd3:  board_word = {wdog_led, 15'd0, watchdog_period};
            4'd4:  board_word = HW_VERSION;
            4'd5:  board_word = temp_word;
            4'd6:  board_word = {24'd0, dout_r};
            4'd7:  board_word = FW_VERSION;
            4'd10: board_word = din_word;
            4'd11: board_word = HAS_ETHERNET ? ip_addr : 32'd0;
            4'd12: board_word = ETH_STATUS;
            // 15: GIT_DESC exists from Rev 9 on; reads 0 here.
            default: board_word = 32'd0;
        endcase
    endfunction
    function [31:0] axis_word(input [1:0] ax, input [3:0] r);
        case (r)
            4'd0:  axis_word = adc_word[32*ax +: 32];
            4'd1:  axis_word = {16'd0, dac_cmd[ax]};
            4'd4:  axis_word = preload[ax];
            4'd5:  axis_word = pos_word[32*ax +: 32];
            4'd6:  axis_word = enc_period[32*ax +: 32];
            4'd7:  axis_word = enc_qtr1[32*ax +: 32];
            4'd9:  axis_word = enc_qtr5[32*ax +: 32];
            4'd10: axis_word = enc_run[32*ax +: 32];
            // MOTOR_CONFIG (MotorChannelQLA.v l.79): bits 31/30 as
            // written, voltage (expander) and current control available.
            4'd11: axis_word = {no_safety[ax], force_dis[ax], 4'd0, 1'b1, 1'b1,
                                en_delay[ax], 1'b0, cur_limit[ax]};
            4'd12: axis_word = mstat_word[32*ax +: 32];
            default: axis_word = 32'd0;
        endcase
    endfunction

    wire [15:0] rd_addr_of [0:1];
    wire [31:0] rd_data_of [0:1];
    assign rd_addr_of[0] = rd_addr;
    assign rd_addr_of[1] = rd_addr_b;
    generate
        for (g = 0; g < 2; g = g + 1) begin : port
            wire [15:0] addr = rd_addr_of[g];
            reg  [31:0] chan_word [0:4];    // board, axes 1-4
            reg  [2:0]  chan;               // 0 board, 1-4 axis, 5 none
            integer c;
            always @(posedge clk) begin
                chan_word[0] <= board_word(addr[3:0]);
                for (c = 0; c < 4; c = c + 1)
                    chan_word[c + 1] <= axis_word(c[1:0], addr[3:0]);
                chan <= (addr[15:8] != 8'h00 || addr[7:4] > 4'd4) ? 3'd5 : addr[6:4];
            end
            assign rd_data_of[g] = (chan <= 3'd4) ? chan_word[chan] : 32'd0;
        end
    endgenerate
    assign rd_data   = rd_data_of[0];
    assign rd_data_b = rd_data_of[1];
    wire       rd_main = (rd_addr[15:8] == 8'h00);
    wire [3:0] rd_chan = rd_addr[7:4];
    wire [3:0] rd_reg  = rd_addr[3:0];
    wire [1:0] rd_ax   = rd_chan[1:0] - 2'd1;

    // ---- writes ------------------------------------------------------------
    // PHY_CTRL: a read is the bare register number, a write
    // 0x1000 | reg << 8 | data; any other word is stored and does nothing.
    wire phy_ctrl_wr = wr_board && wr_reg == 4'd1;
    wire phy_rd_req  = wr_data[31:4] == 28'd0;
    wire phy_wr_req  = wr_data[31:12] == 20'd1;

    integer i;
    always @(posedge clk) begin
        if (rst || reboot) begin
            phy_ctrl         <= 32'd0;
            phy_data         <= 16'd0;
            wdog_led         <= 1'b0;
            no_safety        <= 4'd0;
            force_dis        <= 4'd0;
            phy_read_pending <= 1'b0;
            phy_read_reg     <= 4'd0;
            phy_req_valid    <= 1'b0;
            phy_req_write    <= 1'b0;
            phy_req_addr     <= 4'd0;
            phy_req_data     <= 8'd0;
            dout_r           <= 8'd0;
            ip_addr          <= 32'hFFFF_FFFF;   // IP_UNASSIGNED (EthernetIO.v)
            overflow         <= 4'd0;
            for (i = 0; i < 4; i = i + 1) begin
                dac_cmd[i]   <= 16'h8000;
                ctrl_mode[i] <= 4'd0;
                preload[i]   <= ENC_NEUTRAL;
                offset[i]    <= {1'b0, ENC_NEUTRAL} - {enc_raw[32*i+31], enc_raw[32*i +: 32]};
                en_delay[i]  <= 8'd120;
                cur_limit[i] <= 15'h0418;   // 200 mA (MotorChannelQLA.v l.61)
            end
        end else begin
            if (phy_req_valid && phy_req_ready) phy_req_valid <= 1'b0;
            if (phy_rd_valid && phy_read_pending && phy_rd_addr == phy_read_reg) begin
                phy_data         <= {4'd0, phy_rd_addr, phy_rd_data};
                phy_read_pending <= 1'b0;
            end
            if (phy_ctrl_wr) begin
                phy_ctrl <= wr_data;
                if (phy_rd_req || phy_wr_req) begin
                    phy_req_valid <= 1'b1;
                    phy_req_write <= phy_wr_req;
                    phy_req_addr  <= wr_data[11:8] & {4{phy_wr_req}} |
                                     wr_data[3:0] & {4{phy_rd_req}};
                    phy_req_data  <= wr_data[7:0];
                    if (phy_rd_req) begin
                        phy_read_pending <= 1'b1;
                        phy_read_reg     <= wr_data[3:0];
                    end
                end
            end
            if (wr_board && wr_reg == 4'd6)
                dout_r <= (dout_r & ~wr_data[15:8]) | (wr_data[7:0] & wr_data[15:8]);
            if (wr_board && wr_reg == 4'd11 && HAS_ETHERNET) ip_addr <= wr_data;
            if (wr_board && wr_reg == 4'd2) phy_data <= wr_data[15:0];
            if (watchdog_set) wdog_led <= wr_data[31];
            if (cmd_wr) begin
                dac_cmd[wr_ax]   <= wr_data[15:0];
                ctrl_mode[wr_ax] <= wr_data[27:24];
            end
            if (wr_axis && wr_reg == 4'd4) begin
                preload[wr_ax]  <= {8'd0, wr_data[23:0]};
                offset[wr_ax]   <= {9'd0, wr_data[23:0]} -
                                   {enc_raw[32*wr_ax+31], enc_raw[32*wr_ax +: 32]};
                overflow[wr_ax] <= 1'b0;
            end
            // MOTOR_CONFIG: bits 31/30 stored; 25/24 load the delay and
            // the limit (MotorChannelQLA.v l.196-199).
            if (mcfg_wr) begin
                no_safety[wr_ax] <= wr_data[31];
                force_dis[wr_ax] <= wr_data[30];
                if (wr_data[25]) en_delay[wr_ax]  <= wr_data[23:16];
                if (wr_data[24]) cur_limit[wr_ax] <= wr_data[14:0];
            end
            // A read of ENC_POSITION latches an out-of-range count.
            if (rt_sample)
                overflow <= {pos_word[120], pos_word[88], pos_word[56], pos_word[24]};
            else if (rd_strobe && rd_main && rd_chan >= 4'd1 && rd_chan <= 4'd4 &&
                rd_reg == 4'd5)
                overflow[rd_ax] <= pos_word[32*rd_ax + 24];
        end
    end
endmodule

`default_nettype wire
