// link_rx: asynchronous packet receiver.
//
// Takes the bits phy_ctl_rx delivers (2, 4 or 8 per clock at S100, S200,
// S400), assembles quadlets (big-endian, first bit = bit 31), runs the
// 1394 CRC over the same steps the PHY delivers them in (crc32_1394), and
// checks the header CRC (after the tcode's header quadlets) and the data
// CRC (after the padded data block). Facts: shared/spec/ieee1394.md
// ("Transaction codes", "Header layout", "CRC").
//
// The header quadlets are kept in registers; data quadlets go to the
// receive buffer (one of two 512-quadlet slots, alternating per packet, so
// one packet can be acted on while the next arrives). When the packet ends
// a descriptor is offered (valid/ready) with the CRC results: nothing is
// acted on before that point, so a packet whose header or data CRC fails
// has no effect at all.
//
// early_for_me pulses once the first quadlet names this node (this
// physical ID, whatever the bus ID; a tcode with a header CRC): the node asks for the bus
// with an immediate request then, so its ack can follow the packet at once.
`default_nettype none

module link_rx (
    input  wire        clk,
    input  wire        rst,
    input  wire [31:0] now,           // free-running clock count
    input  wire [5:0]  phy_id,        // this node's physical ID
    input  wire        phy_id_valid,
    // From phy_ctl_rx.
    input  wire        rx_start,
    input  wire [1:0]  rx_speed,
    input  wire        rx_valid,
    input  wire [7:0]  rx_bits,
    input  wire        rx_end,
    // Receive buffer write port (slot in bit 9).
    output reg         buf_wr_en,
    output reg  [9:0]  buf_wr_addr,
    output reg  [31:0] buf_wr_data,
    // Early destination match.
    output reg         early_for_me,
    // Packet descriptor.
    output reg         pkt_valid,
    input  wire        pkt_ready,
    output reg  [31:0] pkt_q0,        // dest:16 tl:6 rt:2 tcode:4 pri:4
    output reg  [31:0] pkt_q1,        // source:16 offset_high:16 (or rcode)
    output reg  [31:0] pkt_q2,        // offset_low:32
    output reg  [31:0] pkt_q3,        // quadlet data, or data_length:16 ext:16
    output reg         pkt_hdr_ok,    // header CRC present and correct
    output reg         pkt_has_data,  // a data block (length > 0) and its CRC
    output reg         pkt_data_ok,   // the data CRC is correct
    output reg         pkt_len_ok,    // every declared quadlet arrived
    output reg         pkt_slot,      // buffer slot of its data
    output reg  [31:0] pkt_time,      // `now` when the packet ended
    output reg         pkt_early,     // early_for_me fired for it
    output reg         overrun        // a descriptor was not taken in time
);
    // Quadlets before the header CRC, by tcode (0: no header CRC).
    function [2:0] header_quadlets(input [3:0] tcode);
        case (tcode)
            4'h0, 4'h1, 4'h5, 4'h6, 4'h7, 4'h8, 4'h9, 4'hB: header_quadlets = 3'd4;
            4'h2, 4'h4: header_quadlets = 3'd3;
            4'hA: header_quadlets = 3'd1;
            default: header_quadlets = 3'd0;
        endcase
    endfunction

    // Block tcodes whose q3 carries data_length and that carry data.
    function has_block(input [3:0] tcode);
        has_block = (tcode == 4'h1) || (tcode == 4'h7) || (tcode == 4'h9) ||
                    (tcode == 4'hB);
    endfunction

    reg  [31:0] crc;       // running CRC register
    reg  [31:0] crc_q;     // CRC register at the last quadlet boundary
    reg  [29:0] shift;     // bits of the quadlet so far (low end)
    reg  [5:0]  bitpos;    // bits of the current quadlet so far
    reg  [10:0] qidx;      // quadlets completed
    reg  [1:0]  width;
    reg         slot;
    reg         active;
    reg  [2:0]  hlen;      // header quadlets (valid after quadlet 0)
    reg  [10:0] dquads;    // data quadlets (valid after quadlet 3)
    reg         has_data;
    reg         hdr_ok, data_ok;
    reg  [31:0] q0, q1, q2, q3;
    reg         early_fired;

    wire [31:0] crc_next;
    crc32_1394 crc_step (
        .crc_in(crc), .data(rx_bits), .width(width), .crc_out(crc_next));

    reg [31:0] shift_next;
    reg [5:0]  bitpos_next;
    always @* begin
        case (width)
            2'd0: begin
                shift_next  = {shift[29:0], rx_bits[7:6]};
                bitpos_next = bitpos + 6'd2;
            end
            2'd1: begin
                shift_next  = {shift[27:0], rx_bits[7:4]};
                bitpos_next = bitpos + 6'd4;
            end
            default: begin
                shift_next  = {shift[23:0], rx_bits};
                bitpos_next = bitpos + 6'd8;
            end
        endcase
    end

    wire        quad_done = active && rx_valid && (bitpos_next == 6'd32);
    wire [2:0]  hl_now    = (qidx == 11'd0) ? header_quadlets(shift_next[7:4]) : hlen;
    // Quadlet indices of the header CRC, the first data quadlet and the data
    // CRC, registered from hlen and dquads: those are set at the ends of
    // quadlets 0 and 3, and the next quadlet ends at least four clocks
    // later. (At quadlet 0 hlen is still 0, which no comparison below
    // mistakes for a header CRC: they all ask for hlen != 0 or has_data.)
    reg  [10:0] hcrc_idx, data_base, dcrc_idx;
    always @(posedge clk) begin
        hcrc_idx  <= {8'd0, hlen};
        data_base <= {8'd0, hlen} + 11'd1;
        dcrc_idx  <= {8'd0, hlen} + 11'd1 + dquads;
    end
    // Quadlets the packet needs (header, its CRC, data and its CRC), for
    // the end of the packet, which may come the clock after a quadlet.
    wire [10:0] needed = (hlen == 3'd0) ? 11'd1 :
                         (has_data ? {8'd0, hlen} + 11'd2 + dquads : {8'd0, hlen} + 11'd1);
    // data_length of the packet in q3 (bytes) -> quadlets, rounded up.
    wire [15:0] q3_len    = shift_next[31:16];
    wire [11:0] q3_round  = {1'b0, q3_len[12:2]} + {11'd0, (q3_len[1:0] != 2'd0)};
    wire [10:0] q3_quads  = (q3_len[15:13] != 3'd0 || q3_round[11]) ? 11'h7FF :
                            q3_round[10:0];


    always @(posedge clk) begin
        buf_wr_en    <= 1'b0;
        early_for_me <= 1'b0;
        overrun      <= 1'b0;
        if (pkt_valid && pkt_ready) pkt_valid <= 1'b0;
        if (rst) begin
            active    <= 1'b0;
            slot      <= 1'b0;
            pkt_valid <= 1'b0;
            crc       <= 32'hFFFF_FFFF;
            crc_q     <= 32'hFFFF_FFFF;
            shift     <= 30'd0;
            bitpos    <= 6'd0;
            qidx      <= 11'd0;
            width     <= 2'd2;
            hlen      <= 3'd0;
            dquads    <= 11'd0;
            has_data  <= 1'b0;
            hdr_ok    <= 1'b0;
            data_ok   <= 1'b0;
            q0 <= 32'd0; q1 <= 32'd0; q2 <= 32'd0; q3 <= 32'd0;
            early_fired <= 1'b0;
        end else if (rx_start) begin
            early_fired <= 1'b0;
            active   <= 1'b1;
            slot     <= ~slot;
            width    <= rx_speed;
            crc      <= 32'hFFFF_FFFF;
            crc_q    <= 32'hFFFF_FFFF;
            shift    <= 30'd0;
            bitpos   <= 6'd0;
            qidx     <= 11'd0;
            hlen     <= 3'd0;
            dquads   <= 11'd0;
            has_data <= 1'b0;
            hdr_ok   <= 1'b0;
            data_ok  <= 1'b0;
            q0 <= 32'd0; q1 <= 32'd0; q2 <= 32'd0; q3 <= 32'd0;
        end else if (active && rx_valid) begin
            shift <= shift_next[29:0];
            if (!quad_done) begin
                bitpos <= bitpos_next;
                crc    <= crc_next;
            end else begin
                bitpos <= 6'd0;
                if (qidx != 11'h7FF) qidx <= qidx + 11'd1;
                // The CRC restarts after the header CRC quadlet.
                if (qidx == hcrc_idx && hlen != 3'd0) begin
                    crc   <= 32'hFFFF_FFFF;
                    crc_q <= 32'hFFFF_FFFF;
                end else begin
                    crc   <= crc_next;
                    crc_q <= crc_next;
                end
                case (qidx)
                    11'd0: begin
                        q0   <= shift_next;
                        hlen <= hl_now;
                        if (phy_id_valid && hl_now != 3'd0 &&
                            shift_next[21:16] == phy_id && phy_id != 6'h3F) begin
                            early_for_me <= 1'b1;
                            early_fired  <= 1'b1;
                        end
                    end
                    11'd1: q1 <= shift_next;
                    11'd2: q2 <= shift_next;
                    11'd3: begin
                        q3 <= shift_next;
                        if (has_block(q0[7:4]) && q3_len != 16'd0) begin
                            has_data <= 1'b1;
                            dquads   <= q3_quads;
                        end
                    end
                    default: ;
                endcase
                if (hlen != 3'd0 && qidx == hcrc_idx)
                    hdr_ok <= (shift_next == ~crc_q);
                if (has_data && qidx == dcrc_idx)
                    data_ok <= (shift_next == ~crc_q);
                if (has_data && qidx >= data_base && qidx < dcrc_idx &&
                    (qidx - data_base) < 11'd512) begin
                    buf_wr_en   <= 1'b1;
                    buf_wr_addr <= {slot, qidx[8:0] - data_base[8:0]};
                    buf_wr_data <= shift_next;
                end
            end
        end else if (active && rx_end) begin
            active <= 1'b0;
            if (pkt_valid && !pkt_ready) begin
                overrun <= 1'b1;
            end else begin
                pkt_valid    <= 1'b1;
                pkt_q0       <= q0;
                pkt_q1       <= q1;
                pkt_q2       <= q2;
                pkt_q3       <= q3;
                pkt_hdr_ok   <= hdr_ok && (qidx >= {8'd0, hlen} + 11'd1);
                pkt_has_data <= has_data;
                pkt_data_ok  <= data_ok;
                pkt_len_ok   <= (qidx >= needed);
                pkt_slot     <= slot;
                pkt_time     <= now;
                pkt_early    <= early_fired;
            end
        end
    end
endmodule

`default_nettype wire
