// phy_lreq_tx: the link's request line to the PHY (LREQ), one request at a
// time as a serial frame, most significant bit first, one bit per clock.
//
// Frame (1394a PHY-link interface; shared/spec/ieee1394.md): a start bit (1),
// a 3-bit request type, then the fields of that type, then a stop bit (0):
//   bus request (0 imm, 1 iso, 2 priority, 3 fair): speed (3 bits:
//     000 S100, 010 S200, 100 S400)                          -> 8 bits
//   register read (4): register address (4 bits)             -> 9 bits
//   register write (5): address (4 bits), data (8 bits)      -> 17 bits
//   acceleration control (6): enable bit                     -> 6 bits
// LREQ rests low between frames.
`default_nettype none

module phy_lreq_tx (
    input  wire       clk,
    input  wire       rst,
    // Request (valid/ready): accepted when both are high.
    input  wire       req_valid,
    output wire       req_ready,
    input  wire [2:0] req_type,   // 0..6 as above
    input  wire [2:0] req_speed,  // bus requests: speed code
    input  wire [3:0] req_addr,   // register requests: PHY register
    input  wire [7:0] req_data,   // register write: value; accel: bit 0
    output reg        lreq
);
    localparam [2:0] T_RDREG = 3'd4, T_WRREG = 3'd5, T_ACCEL = 3'd6;

    reg [16:0] shift;  // remaining bits, next one in bit 16
    reg [4:0]  left;   // bits still to send

    wire   busy      = (left != 5'd0);   // a frame is on the line
    assign req_ready = !busy;

    // The frame of a request, left-aligned in 17 bits, and its length.
    reg [16:0] frame;
    reg [4:0]  frame_len;
    always @* begin
        case (req_type)
            T_RDREG: begin
                frame = {1'b1, req_type, req_addr, 1'b0, 8'd0};
                frame_len = 5'd9;
            end
            T_WRREG: begin
                frame = {1'b1, req_type, req_addr, req_data, 1'b0};
                frame_len = 5'd17;
            end
            T_ACCEL: begin
                frame = {1'b1, req_type, req_data[0], 1'b0, 11'd0};
                frame_len = 5'd6;
            end
            default: begin
                frame = {1'b1, req_type, req_speed, 1'b0, 9'd0};
                frame_len = 5'd8;
            end
        endcase
    end

    always @(posedge clk) begin
        if (rst) begin
            shift <= 17'd0;
            left  <= 5'd0;
            lreq  <= 1'b0;
        end else if (req_valid && req_ready) begin
            lreq  <= frame[16];
            shift <= {frame[15:0], 1'b0};
            left  <= frame_len - 5'd1;
        end else if (busy) begin
            lreq  <= shift[16];
            shift <= {shift[15:0], 1'b0};
            left  <= left - 5'd1;
        end else begin
            lreq <= 1'b0;
        end
    end
endmodule

`default_nettype wire
