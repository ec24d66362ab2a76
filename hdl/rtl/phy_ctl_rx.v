// phy_ctl_rx: what the PHY tells the link on CTL[1:0] and D[7:0].
//
// CTL driven by the PHY (shared/spec/ieee1394.md, "Link-PHY interface"):
//   00 idle, 01 receive, 10 status, 11 grant.
// Receive: one or more cycles of data-on (D = 0xFF), one cycle of speed
// code (S100 D[7:6] = 00, S200 D[7:4] = 0100, S400 D = 0x50), then the
// packet's bits, 2/4/8 per clock on D[7:6]/D[7:4]/D[7:0] (earliest bit in
// D[7]), until CTL leaves receive. A receive that ends during data-on (a
// null packet) is not reported.
// Status: 2 bits per clock on D[7:6], S[0] first, for 2 cycles (4 status
// bits) or 8 cycles (status bits, register address S[4:7], register data
// S[8:15]); reported when CTL leaves status. status_bits holds S[0] in
// bit 15: 15 arbitration reset gap, 14 subaction gap, 13 bus reset,
// 12 PHY interrupt, 11:8 register address, 7:0 register data.
// Grant: reported once per grant.
//
// The pins are registered once on entry; every output is registered, so an
// event on the pins is reported two clocks later. While the link drives
// the interface (link_owns) the PHY-side states are ignored.
`default_nettype none

module phy_ctl_rx (
    input  wire        clk,
    input  wire        rst,
    input  wire [1:0]  ctl_i,
    input  wire [7:0]  d_i,
    input  wire        link_owns,
    output reg         rx_start,      // a packet begins: rx_speed is valid
    output reg  [1:0]  rx_speed,      // 0 S100, 1 S200, 2 S400
    output reg         rx_valid,      // rx_bits carries this clock's bits
    output reg  [7:0]  rx_bits,
    output reg         rx_end,        // the packet ended (after rx_start)
    output reg         status_valid,  // a status transfer ended
    output reg  [15:0] status_bits,
    output reg         status_full,   // it carried register data (16 bits)
    output reg         grant          // the PHY granted the bus
);
    localparam [1:0] CTL_IDLE = 2'b00, CTL_RECEIVE = 2'b01,
                     CTL_STATUS = 2'b10, CTL_GRANT = 2'b11;
    localparam [1:0] S_IDLE = 2'd0, S_DATA_ON = 2'd1, S_DATA = 2'd2,
                     S_STATUS = 2'd3;

    reg [1:0]  ctl_q;
    reg [7:0]  d_q;
    reg [1:0]  state;
    reg [15:0] shift;
    reg [3:0]  count;
    reg        granted;

    always @(posedge clk) begin
        if (rst) begin
            ctl_q <= CTL_IDLE;
            d_q   <= 8'd0;
        end else begin
            ctl_q <= link_owns ? CTL_IDLE : ctl_i;
            d_q   <= d_i;
        end
    end

    always @(posedge clk) begin
        rx_start     <= 1'b0;
        rx_valid     <= 1'b0;
        rx_end       <= 1'b0;
        status_valid <= 1'b0;
        grant        <= 1'b0;
        if (rst) begin
            state       <= S_IDLE;
            rx_speed    <= 2'd0;
            rx_bits     <= 8'd0;
            status_bits <= 16'd0;
            status_full <= 1'b0;
            shift       <= 16'd0;
            count       <= 4'd0;
            granted     <= 1'b0;
        end else begin
            // A status transfer ends when CTL leaves status.
            if (state == S_STATUS && ctl_q != CTL_STATUS && count >= 4'd2) begin
                status_valid <= 1'b1;
                status_full  <= (count >= 4'd8);
                status_bits  <= (count >= 4'd8) ? shift : {shift[3:0], 12'd0};
            end
            // A receive ends when CTL leaves receive.
            if (state == S_DATA && ctl_q != CTL_RECEIVE) rx_end <= 1'b1;
            granted <= (ctl_q == CTL_GRANT);
            case (ctl_q)
                CTL_RECEIVE: begin
                    if (state == S_DATA) begin
                        rx_valid <= 1'b1;
                        rx_bits  <= d_q;
                    end else if (state == S_DATA_ON) begin
                        if (d_q != 8'hFF) begin
                            rx_start <= 1'b1;
                            state    <= S_DATA;
                            if (d_q[7:6] == 2'b00)      rx_speed <= 2'd0;
                            else if (d_q[7:4] == 4'b0100) rx_speed <= 2'd1;
                            else                          rx_speed <= 2'd2;
                        end
                    end else begin
                        state <= S_DATA_ON;
                    end
                end
                CTL_STATUS: begin
                    if (state != S_STATUS) begin
                        state <= S_STATUS;
                        shift <= {14'd0, d_q[7:6]};
                        count <= 4'd1;
                    end else begin
                        shift <= {shift[13:0], d_q[7:6]};
                        if (count != 4'd15) count <= count + 4'd1;
                    end
                end
                CTL_GRANT: begin
                    state <= S_IDLE;
                    if (!granted) grant <= 1'b1;
                end
                default: state <= S_IDLE;
            endcase
        end
    end
endmodule

`default_nettype wire
