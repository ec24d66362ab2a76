// tb_bus: three firelink_node boards (board IDs 1, 2, 3) for the bus test.
// Each node's PHY-side pins are wires the Python bus model drives; the QLA
// inputs are driven per node from the testbench.
`default_nettype none

module tb_bus #(
    parameter integer CHAIN = 1   // passed to every node
) (
    input  wire clk,
    input  wire rst
);
    genvar i;
    generate
        for (i = 0; i < 3; i = i + 1) begin : n
            reg  [1:0]   ctl_i;
            reg  [7:0]   d_i;
            wire [1:0]   ctl_o;
            wire [7:0]   d_o;
            wire         oe, lreq, phy_id_valid, power_enable, relay_on;
            wire [5:0]   phy_id;
            wire [31:0]  now;
            wire [3:0]   amp_enable;
            wire [63:0]  dac_out;
            wire [7:0]   dout;
            wire         overrun, underrun;
            reg  [127:0] adc;
            firelink_node #(.BOARD_ID(i + 1), .CHAIN(CHAIN)) node (
                .clk(clk), .rst(rst),
                .phy_ctl_i(ctl_i), .phy_d_i(d_i), .phy_ctl_o(ctl_o), .phy_d_o(d_o),
                .phy_oe(oe), .phy_lreq(lreq),
                .adc(adc), .enc_raw(128'd0), .enc_period(128'd0), .enc_qtr1(128'd0),
                .enc_qtr5(128'd0), .enc_run(128'd0), .enc_a(4'd0), .enc_b(4'd0),
                .enc_index(4'd0), .neg_limit(4'd0), .pos_limit(4'd0), .home(4'd0),
                .temperature(16'd0), .supply_present(1'b1), .supply_good(1'b0),
                .power_enable(power_enable), .relay_on(relay_on),
                .amp_enable(amp_enable), .dac_out(dac_out), .dout(dout),
                .phy_id(phy_id), .phy_id_valid(phy_id_valid), .now(now),
                .error_rx_overrun(overrun), .error_tx_underrun(underrun));
        end
    endgenerate
endmodule

`default_nettype wire
