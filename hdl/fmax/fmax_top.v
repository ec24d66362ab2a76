// Timing harness for place and route: the node with its QLA side behind
// shift registers, so that the design fits a real package.
//
// `firelink_node` exposes the QLA's sensors and actuators as parallel ports
// (810 input bits, 119 output bits), far more than any FPGA package has
// pins. On the FPGA1394 board those signals come from registers fed by the
// QLA's serial ADCs, DACs and encoder counters, never straight from pins.
// This harness stands in for them: one serial input shifts through a chain
// of flip-flops that drives every QLA input, and every QLA-side output is
// loaded into a second chain that shifts out on one pin. Both chains are
// registers at the node's boundary, so the paths that decide Fmax are the
// node's own (PHY link, request handler, register file, hub, broadcast),
// and nothing of the node is optimised away (every output reaches a pin).
//
// The PHY-link interface keeps its real pins (it is what runs at the
// 49.152 MHz PHY clock on the board).
//
// Used by scripts/bench-hdl only; not part of the node.

`default_nettype none

module fmax_top (
    input  wire       clk,
    input  wire       rst,
    // PHY-link interface, as on the board.
    input  wire [1:0] phy_ctl_i,
    input  wire [7:0] phy_d_i,
    output wire [1:0] phy_ctl_o,
    output wire [7:0] phy_d_o,
    output wire       phy_oe,
    output wire       phy_lreq,
    // QLA side, serialised.
    input  wire       qla_in_serial,
    input  wire       qla_out_load,
    output wire       qla_out_serial
);
    // Widths of the node's QLA-side ports, in port order.
    localparam integer IN_BITS  = 6 * 128 + 6 * 4 + 16 + 2;   // 810
    localparam integer OUT_BITS = 1 + 1 + 4 + 64 + 8 + 6 + 1 + 32 + 1 + 1; // 119

    reg [IN_BITS-1:0]  in_chain;
    reg [OUT_BITS-1:0] out_chain;

    always @(posedge clk) begin
        in_chain <= {in_chain[IN_BITS-2:0], qla_in_serial};
    end

    wire         power_enable, relay_on, phy_id_valid;
    wire         error_rx_overrun, error_tx_underrun;
    wire [3:0]   amp_enable;
    wire [63:0]  dac_out;
    wire [7:0]   dout;
    wire [5:0]   phy_id;
    wire [31:0]  now;

    firelink_node #(.BOARD_ID(0), .CHAIN(1)) node (
        .clk(clk),
        .rst(rst),
        .phy_ctl_i(phy_ctl_i),
        .phy_d_i(phy_d_i),
        .phy_ctl_o(phy_ctl_o),
        .phy_d_o(phy_d_o),
        .phy_oe(phy_oe),
        .phy_lreq(phy_lreq),
        .adc(in_chain[127:0]),
        .enc_raw(in_chain[255:128]),
        .enc_period(in_chain[383:256]),
        .enc_qtr1(in_chain[511:384]),
        .enc_qtr5(in_chain[639:512]),
        .enc_run(in_chain[767:640]),
        .enc_a(in_chain[771:768]),
        .enc_b(in_chain[775:772]),
        .enc_index(in_chain[779:776]),
        .neg_limit(in_chain[783:780]),
        .pos_limit(in_chain[787:784]),
        .home(in_chain[791:788]),
        .temperature(in_chain[807:792]),
        .supply_present(in_chain[808]),
        .supply_good(in_chain[809]),
        .power_enable(power_enable),
        .relay_on(relay_on),
        .amp_enable(amp_enable),
        .dac_out(dac_out),
        .dout(dout),
        .phy_id(phy_id),
        .phy_id_valid(phy_id_valid),
        .now(now),
        .error_rx_overrun(error_rx_overrun),
        .error_tx_underrun(error_tx_underrun)
    );

    always @(posedge clk) begin
        if (qla_out_load)
            out_chain <= {power_enable, relay_on, amp_enable, dac_out, dout,
                          phy_id, phy_id_valid, now, error_rx_overrun,
                          error_tx_underrun};
        else
            out_chain <= {out_chain[OUT_BITS-2:0], 1'b0};
    end
    assign qla_out_serial = out_chain[OUT_BITS-1];
endmodule

`default_nettype wire
