// phy_link_if: the link side of the IEEE 1394a PHY-link interface
// (shared/spec/ieee1394.md, "Link-PHY interface"), at the PHY's 49.152 MHz
// clock.
//
// Pins: CTL[1:0] and D[7:0] are shared with the PHY; here they are split
// into inputs, outputs and one output enable (an FPGA top level puts them
// on tristate pads); LREQ is the link's serial request line.
// - Receive and status transfers are decoded by phy_ctl_rx; packets go on
//   to link_rx.
// - Bus requests (immediate for acks, isochronous-style for the status
//   broadcast, fair or priority) and PHY register reads and writes share
//   the LREQ line (phy_lreq_tx); a bus request goes first.
// - After a grant the link drives the lines (phy_data_tx).
// - A status transfer with the bus-reset bit reports a bus reset; the
//   physical ID is taken from the PHY register 0 status the PHY sends after
//   self-ID (bits 7:2) and from any read of register 0. Register reads
//   answered by status transfers come out on reg_rd_*.
`default_nettype none

module phy_link_if (
    input  wire       clk,
    input  wire       rst,
    // Pins.
    input  wire [1:0] ctl_i,
    input  wire [7:0] d_i,
    output wire [1:0] ctl_o,
    output wire [7:0] d_o,
    output wire       oe,
    output wire       lreq,
    // Receive stream.
    output wire       rx_start,
    output wire [1:0] rx_speed,
    output wire       rx_valid,
    output wire [7:0] rx_bits,
    output wire       rx_end,
    // Bus request.
    input  wire       busreq_valid,
    output wire       busreq_ready,
    input  wire [2:0] busreq_type,   // 0 imm, 1 iso, 2 priority, 3 fair
    output wire       grant,
    input  wire       cancel,
    // Transmit bytes.
    input  wire       tx_valid,
    output wire       tx_ready,
    input  wire [7:0] tx_data,
    input  wire       tx_last,
    input  wire       tx_hold,
    output wire       tx_done,
    output wire       tx_underrun,
    // PHY register access.
    input  wire       reg_valid,
    output wire       reg_ready,
    input  wire       reg_write,
    input  wire [3:0] reg_addr,
    input  wire [7:0] reg_wdata,
    output reg        reg_rd_valid,
    output reg  [3:0] reg_rd_addr,
    output reg  [7:0] reg_rd_data,
    // Bus state.
    output reg        bus_reset,
    output reg  [5:0] phy_id,
    output reg        phy_id_valid
);
    localparam [2:0] SPEED_S400 = 3'b100;
    localparam [2:0] T_RDREG = 3'd4, T_WRREG = 3'd5;

    wire        owns;
    wire        status_valid, status_full;
    // The gap and interrupt bits (15, 14, 12) are not used by this link.
    /* verilator lint_off UNUSEDSIGNAL */
    wire [15:0] status_bits;
    /* verilator lint_on UNUSEDSIGNAL */

    phy_ctl_rx ctl_rx (
        .clk(clk), .rst(rst), .ctl_i(ctl_i), .d_i(d_i), .link_owns(owns),
        .rx_start(rx_start), .rx_speed(rx_speed), .rx_valid(rx_valid),
        .rx_bits(rx_bits), .rx_end(rx_end), .status_valid(status_valid),
        .status_bits(status_bits), .status_full(status_full), .grant(grant));

    phy_data_tx data_tx (
        .clk(clk), .rst(rst), .grant(grant), .cancel(cancel),
        .tx_valid(tx_valid), .tx_ready(tx_ready), .tx_data(tx_data),
        .tx_last(tx_last), .tx_hold(tx_hold), .ctl_o(ctl_o), .d_o(d_o),
        .oe(oe), .owns(owns), .tx_done(tx_done), .underrun(tx_underrun));

    // LREQ: bus requests before register requests.
    wire       lreq_ready;
    wire       take_bus = busreq_valid;
    wire       take_reg = !busreq_valid && reg_valid;
    assign busreq_ready = lreq_ready;
    assign reg_ready    = lreq_ready && !busreq_valid;
    phy_lreq_tx lreq_tx (
        .clk(clk), .rst(rst), .req_valid(take_bus || take_reg),
        .req_ready(lreq_ready),
        .req_type(take_bus ? busreq_type : (reg_write ? T_WRREG : T_RDREG)),
        .req_speed(SPEED_S400), .req_addr(reg_addr), .req_data(reg_wdata),
        .lreq(lreq));

    // Status transfers.
    always @(posedge clk) begin
        bus_reset    <= 1'b0;
        reg_rd_valid <= 1'b0;
        if (rst) begin
            phy_id       <= 6'h3F;
            phy_id_valid <= 1'b0;
            reg_rd_addr  <= 4'd0;
            reg_rd_data  <= 8'd0;
        end else if (status_valid) begin
            if (status_bits[13]) begin
                bus_reset    <= 1'b1;
                phy_id_valid <= 1'b0;
            end
            if (status_full) begin
                reg_rd_valid <= 1'b1;
                reg_rd_addr  <= status_bits[11:8];
                reg_rd_data  <= status_bits[7:0];
                if (status_bits[11:8] == 4'd0) begin
                    phy_id       <= status_bits[7:2];
                    phy_id_valid <= 1'b1;
                end
            end
        end
    end
endmodule

`default_nettype wire
