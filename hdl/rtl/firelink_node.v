// firelink_node: one FPGA1394 + QLA1 board at firmware Rev 8, as seen from
// the 1394 bus: the link layer (PHY-link interface, packet receive and
// transmit with CRCs, acks, concatenated read responses) and the board
// logic (register file, real-time blocks, broadcast query snoop, status
// broadcast, hub memory, command-block slicing, watchdog, power and
// amplifier safety). Facts: shared/spec/ieee1394.md, fpga-board.md.
//
// Clock: the PHY's 49.152 MHz SYSCLK. `now` counts its cycles from reset
// and is the board's only notion of time.
//
// The QLA's sensors (ADC words, encoder counter and velocity words,
// switches, temperatures, the motor-supply comparator) are inputs; its
// actuators (power enable, safety relay, amplifier enables, DAC commands,
// digital outputs) are outputs.
`default_nettype none

module firelink_node #(
    parameter integer BOARD_ID = 0,    // rotary switch, 0..15
    parameter integer CHAIN    = 1     // 1: Rev 7+ chained slots; 0: seed-000 TDMA
) (
    input  wire         clk,
    input  wire         rst,
    // PHY-link interface.
    input  wire [1:0]   phy_ctl_i,
    input  wire [7:0]   phy_d_i,
    output wire [1:0]   phy_ctl_o,
    output wire [7:0]   phy_d_o,
    output wire         phy_oe,
    output wire         phy_lreq,
    // QLA inputs.
    input  wire [127:0] adc,
    input  wire [127:0] enc_raw,
    input  wire [127:0] enc_period,
    input  wire [127:0] enc_qtr1,
    input  wire [127:0] enc_qtr5,
    input  wire [127:0] enc_run,
    input  wire [3:0]   enc_a,
    input  wire [3:0]   enc_b,
    input  wire [3:0]   enc_index,
    input  wire [3:0]   neg_limit,
    input  wire [3:0]   pos_limit,
    input  wire [3:0]   home,
    input  wire [15:0]  temperature,
    input  wire         supply_present,
    input  wire         supply_good,
    // QLA outputs.
    output wire         power_enable,
    output wire         relay_on,
    output wire [3:0]   amp_enable,
    output wire [63:0]  dac_out,
    output wire [7:0]   dout,
    // Status.
    output wire [5:0]   phy_id,
    output wire         phy_id_valid,
    output reg  [31:0]  now,
    output wire         error_rx_overrun,
    output wire         error_tx_underrun
);
    initial begin
        if (BOARD_ID < 0 || BOARD_ID > 15) begin
            $display("firelink_node: BOARD_ID must be 0..15");
            $finish;
        end
        if (CHAIN != 0 && CHAIN != 1) begin
            $display("firelink_node: CHAIN must be 0 or 1");
            $finish;
        end
    end
    localparam [3:0] ID = BOARD_ID[3:0];
    localparam       CHAINED = (CHAIN == 1);

    always @(posedge clk) begin
        if (rst) now <= 32'd0;
        else     now <= now + 32'd1;
    end

    // ---- PHY-link interface -------------------------------------------------
    wire       rx_start, rx_valid, rx_end;
    wire [1:0] rx_speed;
    wire [7:0] rx_bits;
    wire       busreq_valid, busreq_ready, grant, cancel;
    wire [2:0] busreq_type;
    wire       tx_valid, tx_ready, tx_last, tx_hold, tx_done;
    wire [7:0] tx_data;
    wire       reg_valid, reg_ready, reg_write, reg_rd_valid;
    wire [3:0] reg_addr, reg_rd_addr;
    wire [7:0] reg_wdata, reg_rd_data;
    wire       bus_reset;

    phy_link_if phy (
        .clk(clk), .rst(rst),
        .ctl_i(phy_ctl_i), .d_i(phy_d_i), .ctl_o(phy_ctl_o), .d_o(phy_d_o),
        .oe(phy_oe), .lreq(phy_lreq),
        .rx_start(rx_start), .rx_speed(rx_speed), .rx_valid(rx_valid),
        .rx_bits(rx_bits), .rx_end(rx_end),
        .busreq_valid(busreq_valid), .busreq_ready(busreq_ready),
        .busreq_type(busreq_type), .grant(grant), .cancel(cancel),
        .tx_valid(tx_valid), .tx_ready(tx_ready), .tx_data(tx_data),
        .tx_last(tx_last), .tx_hold(tx_hold), .tx_done(tx_done),
        .tx_underrun(error_tx_underrun),
        .reg_valid(reg_valid), .reg_ready(reg_ready), .reg_write(reg_write),
        .reg_addr(reg_addr), .reg_wdata(reg_wdata), .reg_rd_valid(reg_rd_valid),
        .reg_rd_addr(reg_rd_addr), .reg_rd_data(reg_rd_data),
        .bus_reset(bus_reset), .phy_id(phy_id), .phy_id_valid(phy_id_valid));

    // ---- receive ----------------------------------------------------------------
    wire        rxb_we;
    wire [9:0]  rxb_waddr, rxb_raddr;
    wire [31:0] rxb_wdata, rxb_rdata;
    sdp_ram #(.WIDTH(32), .DEPTH(1024), .ADDR_BITS(10), .OUT_REG(1)) rx_buffer (
        .clk(clk), .wr_en(rxb_we), .wr_addr(rxb_waddr), .wr_data(rxb_wdata),
        .rd_addr(rxb_raddr), .rd_data(rxb_rdata));

    wire        early_for_me;
    wire        pkt_valid, pkt_ready, pkt_hdr_ok, pkt_has_data, pkt_data_ok;
    wire        pkt_len_ok, pkt_slot, pkt_early;
    wire [31:0] pkt_q0, pkt_q1, pkt_q2, pkt_q3, pkt_time;
    link_rx rx (
        .clk(clk), .rst(rst), .now(now), .phy_id(phy_id),
        .phy_id_valid(phy_id_valid),
        .rx_start(rx_start), .rx_speed(rx_speed), .rx_valid(rx_valid),
        .rx_bits(rx_bits), .rx_end(rx_end),
        .buf_wr_en(rxb_we), .buf_wr_addr(rxb_waddr), .buf_wr_data(rxb_wdata),
        .early_for_me(early_for_me),
        .pkt_valid(pkt_valid), .pkt_ready(pkt_ready),
        .pkt_q0(pkt_q0), .pkt_q1(pkt_q1), .pkt_q2(pkt_q2), .pkt_q3(pkt_q3),
        .pkt_hdr_ok(pkt_hdr_ok), .pkt_has_data(pkt_has_data),
        .pkt_data_ok(pkt_data_ok), .pkt_len_ok(pkt_len_ok), .pkt_slot(pkt_slot),
        .pkt_time(pkt_time), .pkt_early(pkt_early),
        .overrun(error_rx_overrun));

    // ---- board ------------------------------------------------------------------
    wire        wr_en, regs_rd_strobe;
    wire [15:0] wr_addr, handler_rd_addr;
    wire [31:0] wr_data, wr_time, regs_rd_data, regs_rd_data_b;
    wire        wd_fire, wd_timed_out, wd_set, wd_clear, reboot;
    wire [15:0] wd_period, wd_value;
    wire        refresh;
    wire [31:0] refresh_time;
    wire        hr_rt_sample, bc_rt_sample;
    wire [31:0] hr_rt_time, bc_rt_time;

    board_watchdog watchdog (
        .clk(clk), .rst(rst), .now(now), .refresh(refresh),
        .refresh_time(refresh_time), .set_period(wd_set), .period_in(wd_value),
        .clear(wd_clear), .reboot(reboot), .period(wd_period),
        .timed_out(wd_timed_out), .fire(wd_fire));

    board_regs #(.BOARD_ID(ID)) regs (
        .clk(clk), .rst(rst), .now(now),
        .wr_en(wr_en), .wr_addr(wr_addr), .wr_data(wr_data), .wr_time(wr_time),
        .rd_addr(handler_rd_addr), .rd_strobe(regs_rd_strobe),
        .rd_data(regs_rd_data),
        .rd_addr_b(rt_addr_b), .rd_data_b(regs_rd_data_b),
        .rt_sample(hr_rt_sample || bc_rt_sample),
        .watchdog_fire(wd_fire), .watchdog_timed_out(wd_timed_out),
        .watchdog_period(wd_period), .watchdog_set(wd_set),
        .watchdog_value(wd_value), .watchdog_clear(wd_clear), .reboot(reboot),
        .phy_req_valid(reg_valid), .phy_req_ready(reg_ready),
        .phy_req_write(reg_write), .phy_req_addr(reg_addr),
        .phy_req_data(reg_wdata), .phy_rd_valid(reg_rd_valid),
        .phy_rd_addr(reg_rd_addr), .phy_rd_data(reg_rd_data),
        .adc(adc), .enc_raw(enc_raw), .enc_period(enc_period),
        .enc_qtr1(enc_qtr1), .enc_qtr5(enc_qtr5), .enc_run(enc_run),
        .enc_a(enc_a), .enc_b(enc_b), .enc_index(enc_index),
        .neg_limit(neg_limit), .pos_limit(pos_limit), .home(home),
        .temperature(temperature), .supply_present(supply_present),
        .supply_good(supply_good),
        .power_enable(power_enable), .relay_on(relay_on), .amp_enable(amp_enable),
        .dac_out(dac_out), .dout(dout));

    // The real-time block: a timestamp plus registers read through the
    // register file's read ports (a: the handler's block reads, b: the
    // status-broadcast snapshot; no packet is taken while it copies). The
    // register word follows the index by a clock; so does what else
    // makes the quadlet.
    wire [9:0]  rt_index_a, rt_index_b;
    wire [15:0] rt_addr_a, rt_addr_b;
    wire        rt_stamp_a, rt_stamp_b, rt_zero_a, rt_zero_b;
    wire [31:0] rt_extra_a, rt_extra_b;
    wire [31:0] rt_timestamp, rt_data_b;
    realtime_block rt_block (
        .clk(clk), .rst(rst),
        .sample(hr_rt_sample || bc_rt_sample),
        .sample_time(hr_rt_sample ? hr_rt_time : bc_rt_time),
        .restart(reboot), .restart_time(wr_time), .timestamp(rt_timestamp),
        .index_a(rt_index_a), .addr_a(rt_addr_a), .stamp_a(rt_stamp_a), .zero_a(rt_zero_a),
        .extra_a(rt_extra_a),
        .index_b(rt_index_b), .addr_b(rt_addr_b), .stamp_b(rt_stamp_b), .zero_b(rt_zero_b),
        .extra_b(rt_extra_b));
    reg         rt_stamp_b_q, rt_zero_b_q;
    reg  [31:0] rt_extra_b_q;
    always @(posedge clk) begin
        rt_stamp_b_q <= rt_stamp_b;
        rt_zero_b_q  <= rt_zero_b;
        rt_extra_b_q <= rt_extra_b;
    end
    assign rt_data_b = rt_stamp_b_q ? rt_timestamp :
                       (rt_zero_b_q ? 32'd0 : regs_rd_data_b | rt_extra_b_q);

    // Hub.
    wire        query_valid, query_event;
    wire [31:0] query_word, query_time, query_reg, query_at;
    wire        st_valid, st_ready, st_done;
    wire [15:0] st_len;
    wire [31:0] st_time;
    wire [8:0]  hub_src_addr;
    wire        hub_src_sel, hub_src_active;
    wire [15:0] seen;
    wire        seen_event;
    wire [31:0] seen_time;
    wire [15:0] hub_rd_addr;
    wire [31:0] hub_rd_time, hub_rd_data;
    wire        bc_sent, drop_early;
    wire [31:0] snap_rdata;

    broadcast_hub hub (
        .clk(clk), .rst(rst), .reboot(reboot),
        .query_valid(query_valid), .query_word(query_word),
        .query_time(query_time), .query_event(query_event),
        .query_reg(query_reg), .query_at(query_at),
        .st_valid(st_valid), .st_ready(st_ready), .st_len(st_len),
        .st_time(st_time), .st_done(st_done),
        .own_valid(bc_sent), .own_time(now),
        .src_addr(hub_src_addr), .src_sel(hub_src_sel), .src_active(hub_src_active),
        .src_data(hub_src_sel ? snap_rdata : rxb_rdata),
        .seen(seen), .seen_event(seen_event), .seen_time(seen_time),
        .rd_addr(hub_rd_addr), .rd_time(hub_rd_time), .rd_data(hub_rd_data));

    // Status broadcast and its snapshot.
    wire        snap_we, snap_busy, bc_req;
    wire [5:0]  snap_waddr, snap_pl_addr;
    wire [31:0] snap_wdata;
    wire        bc_active;
    sdp_ram #(.WIDTH(32), .DEPTH(64), .ADDR_BITS(6), .OUT_REG(1)) snapshot (
        .clk(clk), .wr_en(snap_we), .wr_addr(snap_waddr), .wr_data(snap_wdata),
        .rd_addr((hub_src_sel && hub_src_active) ? hub_src_addr[5:0] : snap_pl_addr),
        .rd_data(snap_rdata));

    status_broadcast #(.BOARD_ID(ID), .CHAIN(CHAINED)) broadcaster (
        .clk(clk), .rst(rst), .now(now), .phy_id(phy_id),
        .phy_id_valid(phy_id_valid), .bus_reset(bus_reset), .reboot(reboot),
        .query_event(query_event), .query_reg(query_reg), .query_at(query_at),
        .seen(seen), .seen_event(seen_event), .seen_time(seen_time),
        .rt_sample(bc_rt_sample), .rt_sample_time(bc_rt_time),
        .rt_index(rt_index_b), .rt_data(rt_data_b),
        .snap_we(snap_we), .snap_waddr(snap_waddr), .snap_wdata(snap_wdata),
        .snap_busy(snap_busy), .bc_req(bc_req), .bc_sent(bc_sent));

    // Command slicer.
    wire        sl_start, sl_busy, sl_wr_en;
    wire [15:0] sl_len, sl_wr_addr;
    wire [31:0] sl_time, sl_wr_data, sl_wr_time;
    wire [8:0]  sl_rd_addr;
    command_slicer #(.BOARD_ID(ID)) slicer (
        .clk(clk), .rst(rst), .start(sl_start), .length(sl_len),
        .time_in(sl_time), .busy(sl_busy), .rd_addr(sl_rd_addr),
        .rd_data(rxb_rdata), .wr_en(sl_wr_en), .wr_addr(sl_wr_addr),
        .wr_data(sl_wr_data), .wr_time(sl_wr_time));

    // ---- transactions -------------------------------------------------------------
    wire        reply_valid;
    wire [1:0]  reply_kind;
    wire [3:0]  reply_ack;
    wire [31:0] reply_h0, reply_h1, reply_h2, reply_h3;
    wire [9:0]  reply_data_quads;
    wire        pl_rd;
    wire [9:0]  pl_index;
    wire [31:0] pl_data;

    request_handler handler (
        .clk(clk), .rst(rst), .phy_id(phy_id), .phy_id_valid(phy_id_valid),
        .pkt_valid(pkt_valid), .pkt_ready(pkt_ready),
        .pkt_q0(pkt_q0), .pkt_q1(pkt_q1), .pkt_q2(pkt_q2), .pkt_q3(pkt_q3),
        .pkt_hdr_ok(pkt_hdr_ok), .pkt_has_data(pkt_has_data),
        .pkt_data_ok(pkt_data_ok), .pkt_len_ok(pkt_len_ok),
        .pkt_slot(pkt_slot), .pkt_early(pkt_early), .pkt_time(pkt_time),
        .drop_early(drop_early), .snap_busy(snap_busy),
        .rxb_addr(rxb_raddr), .rxb_data(rxb_rdata),
        .wr_en(wr_en), .wr_addr(wr_addr), .wr_data(wr_data), .wr_time(wr_time),
        .regs_rd_addr(handler_rd_addr), .regs_rd_strobe(regs_rd_strobe),
        .regs_rd_data(regs_rd_data),
        .refresh(refresh), .refresh_time(refresh_time),
        .query_valid(query_valid), .query_word(query_word), .query_time(query_time),
        .st_valid(st_valid), .st_ready(st_ready), .st_len(st_len),
        .st_time(st_time), .st_done(st_done),
        .hub_rd_addr(hub_rd_addr), .hub_rd_time(hub_rd_time),
        .hub_rd_data(hub_rd_data),
        .rt_sample(hr_rt_sample), .rt_sample_time(hr_rt_time),
        .rt_index(rt_index_a), .rt_addr(rt_addr_a), .rt_stamp(rt_stamp_a),
        .rt_zero(rt_zero_a), .rt_extra(rt_extra_a), .rt_timestamp(rt_timestamp),
        .sl_start(sl_start), .sl_len(sl_len), .sl_time(sl_time), .sl_busy(sl_busy),
        .sl_rd_addr(sl_rd_addr), .sl_wr_en(sl_wr_en), .sl_wr_addr(sl_wr_addr),
        .sl_wr_data(sl_wr_data), .sl_wr_time(sl_wr_time),
        .hub_src_addr(hub_src_addr),
        .reply_valid(reply_valid), .reply_kind(reply_kind), .reply_ack(reply_ack),
        .reply_h0(reply_h0), .reply_h1(reply_h1), .reply_h2(reply_h2),
        .reply_h3(reply_h3), .reply_data_quads(reply_data_quads),
        .pl_rd(pl_rd), .pl_index(pl_index), .pl_snapshot(bc_active),
        .snap_rd_data(snap_rdata), .snap_rd_addr(snap_pl_addr), .pl_data(pl_data));

    wire        job_valid, job_ready, job_ack, job_pkt;
    wire [3:0]  job_ack_code;
    wire [31:0] job_h0, job_h1, job_h2, job_h3;
    wire [2:0]  job_hdr_quads;
    wire [9:0]  job_data_quads;
    link_ctrl ctrl (
        .clk(clk), .rst(rst), .bus_reset(bus_reset), .phy_id(phy_id),
        .early_for_me(early_for_me),
        .reply_valid(reply_valid), .reply_kind(reply_kind), .reply_ack(reply_ack),
        .reply_h0(reply_h0), .reply_h1(reply_h1), .reply_h2(reply_h2),
        .reply_h3(reply_h3), .reply_data_quads(reply_data_quads),
        .bc_req(bc_req), .bc_sent(bc_sent), .drop_early(drop_early),
        .bc_active(bc_active),
        .busreq_valid(busreq_valid), .busreq_ready(busreq_ready),
        .busreq_type(busreq_type), .grant(grant), .cancel(cancel),
        .tx_done(tx_done),
        .job_valid(job_valid), .job_ready(job_ready), .job_ack(job_ack),
        .job_ack_code(job_ack_code), .job_pkt(job_pkt),
        .job_h0(job_h0), .job_h1(job_h1), .job_h2(job_h2), .job_h3(job_h3),
        .job_hdr_quads(job_hdr_quads), .job_data_quads(job_data_quads));

    link_tx tx (
        .clk(clk), .rst(rst),
        .job_valid(job_valid), .job_ready(job_ready), .job_ack(job_ack),
        .job_ack_code(job_ack_code), .job_pkt(job_pkt),
        .job_h0(job_h0), .job_h1(job_h1), .job_h2(job_h2), .job_h3(job_h3),
        .job_hdr_quads(job_hdr_quads), .job_data_quads(job_data_quads),
        .pl_rd(pl_rd), .pl_index(pl_index), .pl_data(pl_data),
        .tx_valid(tx_valid), .tx_ready(tx_ready), .tx_data(tx_data),
        .tx_last(tx_last), .tx_hold(tx_hold));
endmodule

`default_nettype wire
