// phy_data_tx: the link drives CTL[1:0]/D[7:0] after a grant.
//
// CTL driven by the link (shared/spec/ieee1394.md): 00 idle, 01 transmit,
// 10 hold. After the PHY's grant the link holds the bus (CTL = hold) until
// the first byte is ready, then sends one byte per clock with CTL =
// transmit (S400, D[7:0], earliest bit in D[7]). After the last byte of a
// packet it either asks for another packet in the same bus ownership
// (CTL = hold, then the next packet: an ack followed by a concatenated
// response) or ends with one clock of CTL = idle and releases the lines.
// A grant with nothing to send (cancel) is released the same way.
//
// Bytes arrive on a valid/ready stream; once a packet has started its bytes
// must come one per clock (the framer guarantees it). An underrun is an
// error: the packet is ended at once and `underrun` pulses.
`default_nettype none

module phy_data_tx (
    input  wire       clk,
    input  wire       rst,
    input  wire       grant,       // from phy_ctl_rx
    input  wire       cancel,      // granted, but nothing will be sent
    input  wire       tx_valid,
    output wire       tx_ready,
    input  wire [7:0] tx_data,
    input  wire       tx_last,     // last byte of a packet
    input  wire       tx_hold,     // with tx_last: another packet follows
    output reg  [1:0] ctl_o,
    output reg  [7:0] d_o,
    output reg        oe,          // the link drives CTL and D
    output wire       owns,        // the interface belongs to the link
    output reg        tx_done,     // released (one clock)
    output reg        underrun
);
    localparam [1:0] CTL_IDLE = 2'b00, CTL_TRANSMIT = 2'b01, CTL_HOLD = 2'b10;
    localparam [1:0] S_OFF = 2'd0, S_HOLD = 2'd1, S_XMIT = 2'd2, S_END = 2'd3;

    reg [1:0] state;
    reg       sep;   // one clock of hold between two packets

    assign owns     = (state != S_OFF) || oe;
    assign tx_ready = ((state == S_HOLD) && !sep) || (state == S_XMIT);

    always @(posedge clk) begin
        tx_done  <= 1'b0;
        underrun <= 1'b0;
        if (rst) begin
            state <= S_OFF;
            sep   <= 1'b0;
            ctl_o <= CTL_IDLE;
            d_o   <= 8'd0;
            oe    <= 1'b0;
        end else begin
            case (state)
                S_OFF: begin
                    oe    <= 1'b0;
                    ctl_o <= CTL_IDLE;
                    d_o   <= 8'd0;
                    if (grant) begin
                        state <= S_HOLD;
                        oe    <= 1'b1;
                        ctl_o <= CTL_HOLD;
                    end
                end
                S_HOLD: begin
                    oe <= 1'b1;
                    if (sep) begin
                        sep   <= 1'b0;
                        ctl_o <= CTL_HOLD;
                        d_o   <= 8'd0;
                    end else if (tx_valid) begin
                        ctl_o <= CTL_TRANSMIT;
                        d_o   <= tx_data;
                        if (tx_last) begin
                            state <= tx_hold ? S_HOLD : S_END;
                            sep   <= tx_hold;
                        end else begin
                            state <= S_XMIT;
                        end
                    end else if (cancel) begin
                        ctl_o <= CTL_IDLE;
                        d_o   <= 8'd0;
                        state <= S_END;
                    end else begin
                        ctl_o <= CTL_HOLD;
                        d_o   <= 8'd0;
                    end
                end
                S_XMIT: begin
                    if (tx_valid) begin
                        ctl_o <= CTL_TRANSMIT;
                        d_o   <= tx_data;
                        if (tx_last) begin
                            state <= tx_hold ? S_HOLD : S_END;
                            sep   <= tx_hold;
                        end
                    end else begin
                        underrun <= 1'b1;
                        ctl_o    <= CTL_IDLE;
                        d_o      <= 8'd0;
                        state    <= S_END;
                    end
                end
                default: begin // S_END: one clock of idle, then release
                    if (ctl_o != CTL_IDLE) begin
                        ctl_o <= CTL_IDLE;
                        d_o   <= 8'd0;
                    end else begin
                        oe      <= 1'b0;
                        state   <= S_OFF;
                        tx_done <= 1'b1;
                    end
                end
            endcase
        end
    end
endmodule

`default_nettype wire
