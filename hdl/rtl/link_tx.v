// link_tx: asynchronous packet transmitter (framer).
//
// One job is what the link sends in one bus ownership: an ack (one byte:
// code in the high nibble, its complement in the low nibble), a packet, or
// an ack followed by a concatenated packet (the read response). A packet
// is `hdr_quads` header quadlets, the header CRC, then `data_quads` data
// quadlets fetched from the payload source and the data CRC (no data block
// when data_quads is 0). CRCs are computed on the fly one byte per step by
// crc32_1394 (shared/spec/ieee1394.md, "CRC"). Bytes leave on a
// valid/ready stream for phy_data_tx, which sends them at S400.
//
// Payload source: the framer raises pl_rd with pl_index; the quadlet must
// be on pl_data exactly four clocks later. Quadlets are asked for two
// ahead (kept by parity in two registers), at least eight clocks before
// they are needed, so the bytes never stall.
`default_nettype none

module link_tx (
    input  wire        clk,
    input  wire        rst,
    // Job (valid/ready).
    input  wire        job_valid,
    output wire        job_ready,
    input  wire        job_ack,        // send an ack byte first
    input  wire [3:0]  job_ack_code,
    input  wire        job_pkt,        // send a packet (after the ack)
    input  wire [31:0] job_h0,
    input  wire [31:0] job_h1,
    input  wire [31:0] job_h2,
    input  wire [31:0] job_h3,
    input  wire [2:0]  job_hdr_quads,  // 3 or 4
    input  wire [9:0]  job_data_quads, // 0..512
    // Payload source.
    output reg         pl_rd,
    output reg  [9:0]  pl_index,
    input  wire [31:0] pl_data,
    // Byte stream to phy_data_tx.
    output wire        tx_valid,
    input  wire        tx_ready,
    output wire [7:0]  tx_data,
    output wire        tx_last,
    output wire        tx_hold
);
    localparam [2:0] P_IDLE = 3'd0, P_ACK = 3'd1, P_HDR = 3'd2, P_HCRC = 3'd3,
                     P_DATA = 3'd4, P_DCRC = 3'd5;

    reg [2:0]  phase;
    reg [31:0] cur;        // quadlet being sent, shifted to its current byte
    reg [1:0]  bi;         // byte of it
    reg [2:0]  hi;         // header quadlet index
    reg [9:0]  di;         // data quadlet index
    reg [31:0] crc;
    reg        pkt_after_ack;
    reg [31:0] h0, h1, h2, h3;
    reg [2:0]  hq;
    reg [9:0]  dq;
    reg [31:0] pf [0:1];   // prefetched payload quadlets, by index parity
    reg [3:0]  pending;    // payload reads in flight, by age
    reg [3:1]  pending_odd;// ... and their index parity
    reg        ask_second; // quadlet 1 still to ask for (the clock after 0)

    assign job_ready = (phase == P_IDLE);
    assign tx_valid  = (phase != P_IDLE);
    // cur shifts left a byte per byte sent: the byte on the wire is always
    // its top byte (no multiplexer before the CRC).
    assign tx_data   = cur[31:24];
    wire   last_byte = (phase == P_ACK) || (bi == 2'd3);
    assign tx_last   = (phase == P_ACK) ||
                       (bi == 2'd3 && (phase == P_DCRC ||
                                       (phase == P_HCRC && dq == 10'd0)));
    assign tx_hold   = (phase == P_ACK) && pkt_after_ack;

    wire [31:0] crc_next;
    crc32_1394 crc_step (
        .crc_in(crc), .data(tx_data), .width(2'd2), .crc_out(crc_next));

    function [31:0] header_word(input [2:0] i, input [31:0] a, input [31:0] b,
                                input [31:0] c, input [31:0] d);
        case (i)
            3'd0: header_word = a;
            3'd1: header_word = b;
            3'd2: header_word = c;
            default: header_word = d;
        endcase
    endfunction

    always @(posedge clk) begin
        pl_rd <= 1'b0;
        if (rst) begin
            phase   <= P_IDLE;
            cur     <= 32'd0;
            bi      <= 2'd0;
            hi      <= 3'd0;
            di      <= 10'd0;
            crc     <= 32'hFFFF_FFFF;
            pending <= 4'b0000;
            pending_odd <= 3'b000;
            ask_second  <= 1'b0;
            pf[0]   <= 32'd0;
            pf[1]   <= 32'd0;
            pl_index <= 10'd0;
            pkt_after_ack <= 1'b0;
            h0 <= 32'd0; h1 <= 32'd0; h2 <= 32'd0; h3 <= 32'd0;
            hq <= 3'd4; dq <= 10'd0;
        end else begin
            // Payload reads in flight: capture the data when it is due.
            pending     <= {pending[2:0], 1'b0};
            // pl_index is the index of the read in pending[0].
            pending_odd <= {pending_odd[2:1], pl_index[0]};
            if (pending[3]) pf[pending_odd[3]] <= pl_data;
            if (ask_second) begin
                ask_second <= 1'b0;
                pl_rd      <= 1'b1;
                pl_index   <= 10'd1;
                pending[0] <= 1'b1;
            end
            if (phase == P_IDLE) begin
                if (job_valid) begin
                    h0 <= job_h0; h1 <= job_h1; h2 <= job_h2; h3 <= job_h3;
                    hq <= job_hdr_quads;
                    dq <= job_data_quads;
                    crc <= 32'hFFFF_FFFF;
                    bi  <= 2'd0;
                    hi  <= 3'd0;
                    di  <= 10'd0;
                    pkt_after_ack <= job_pkt;
                    if (job_ack) begin
                        phase <= P_ACK;
                        cur   <= {job_ack_code, ~job_ack_code, 24'd0};
                    end else begin
                        phase <= P_HDR;
                        cur   <= job_h0;
                    end
                    // Ask for the first two payload quadlets now.
                    if (job_pkt && job_data_quads != 10'd0) begin
                        pl_rd    <= 1'b1;
                        pl_index <= 10'd0;
                        pending[0] <= 1'b1;
                        ask_second <= (job_data_quads > 10'd1);
                    end
                end
            end else if (tx_ready) begin
                if (phase != P_ACK) crc <= crc_next;
                if (!last_byte) begin
                    bi  <= bi + 2'd1;
                    cur <= {cur[23:0], 8'd0};
                end else begin
                    bi <= 2'd0;
                    case (phase)
                        P_ACK: begin
                            if (pkt_after_ack) begin
                                phase <= P_HDR;
                                cur   <= h0;
                            end else begin
                                phase <= P_IDLE;
                            end
                        end
                        P_HDR: begin
                            if (hi + 3'd1 == hq) begin
                                phase <= P_HCRC;
                                cur   <= ~crc_next;
                            end else begin
                                hi  <= hi + 3'd1;
                                cur <= header_word(hi + 3'd1, h0, h1, h2, h3);
                            end
                        end
                        P_HCRC: begin
                            crc <= 32'hFFFF_FFFF;
                            if (dq == 10'd0) begin
                                phase <= P_IDLE;
                            end else begin
                                phase <= P_DATA;
                                cur   <= pf[0];
                                di    <= 10'd0;
                                if (dq > 10'd2) begin
                                    pl_rd    <= 1'b1;
                                    pl_index <= 10'd2;
                                    pending[0] <= 1'b1;
                                end
                            end
                        end
                        P_DATA: begin
                            if (di + 10'd1 == dq) begin
                                phase <= P_DCRC;
                                cur   <= ~crc_next;
                            end else begin
                                di  <= di + 10'd1;
                                cur <= pf[~di[0]];
                                if (di + 10'd3 < dq) begin
                                    pl_rd    <= 1'b1;
                                    pl_index <= di + 10'd3;
                                    pending[0] <= 1'b1;
                                end
                            end
                        end
                        default: phase <= P_IDLE; // P_DCRC
                    endcase
                end
            end
        end
    end
endmodule

`default_nettype wire
