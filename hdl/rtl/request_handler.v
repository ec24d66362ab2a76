// request_handler: what the board does with each received packet, and
// what it answers (shared/spec/fpga-board.md; shared/spec/ieee1394.md).
//
// A packet is looked at only once it has ended and both its CRCs are
// known (link_rx). It is taken when it is addressed to this node (the
// physical ID; the bus ID is not compared), to broadcast (63), or to node 0
// at the snooped query (quadlet write to 0x1800) or command (block write
// to 0xFFFF_FFFF_0000) addresses; only packets addressed to this node are
// acknowledged.
// - A truncated packet: nothing, no ack. A header CRC error: nothing, and
//   a read or write request for this node is acknowledged ack_data_error.
// - Quadlet write: the register, the query, or nothing (unmapped);
//   ack_complete.
// - Block write: a data CRC error is answered ack_data_error and changes
//   nothing. Else address 0 takes the real-time write block or this
//   board's slice of a command block (command_slicer); hub memory stores a
//   status broadcast (broadcast_hub); 0x1800 takes the query from its first
//   quadlet; main-space addresses are written register by register;
//   ack_complete.
// - Every taken write refreshes the watchdog, at the packet's clock.
// - Quadlet and block reads: ack_pending and the response concatenated at
//   once (source = this node, tl echoed, rcode complete). A block read of
//   address 0 is the real-time block (sampled at the packet's clock); other
//   block reads read address by address (hub quadlets from the hub). A
//   length of 0 or not whole quadlets gets rcode type_error, above 2048
//   bytes address_error, with no data.
// - Responses to requests the board never makes: ack_complete; a lock
//   request: no ack.
// - A packet for this node that arrives while an earlier one still keeps
//   the handler busy is answered ack_busy_X by link_ctrl and dropped here
//   (drop_early): the requester sends it again.
// Response payload quadlets come from the payload port four clocks after
// the framer asks (registers, real-time block, hub, or the broadcast
// snapshot while the status broadcast goes out).
`default_nettype none

module request_handler (
    input  wire        clk,
    input  wire        rst,
    input  wire [5:0]  phy_id,
    input  wire        phy_id_valid,
    // Packet descriptor (link_rx).
    input  wire        pkt_valid,
    output wire        pkt_ready,
    input  wire [31:0] pkt_q0, pkt_q1, pkt_q2, pkt_q3,
    input  wire        pkt_hdr_ok,
    input  wire        pkt_has_data,
    input  wire        pkt_data_ok,
    input  wire        pkt_len_ok,
    input  wire        pkt_slot,
    input  wire        pkt_early,     // link_ctrl asked for an ack grant
    input  wire [31:0] pkt_time,
    input  wire        drop_early,    // the link answered it busy: ignore it
    input  wire        snap_busy,
    // Receive buffer read (data two clocks after the address).
    output reg  [9:0]  rxb_addr,
    input  wire [31:0] rxb_data,
    // Register file.
    output reg         wr_en,
    output reg  [15:0] wr_addr,
    output reg  [31:0] wr_data,
    output reg  [31:0] wr_time,
    output wire [15:0] regs_rd_addr,
    output wire        regs_rd_strobe,
    input  wire [31:0] regs_rd_data,
    // Watchdog refresh.
    output reg         refresh,
    output reg  [31:0] refresh_time,
    // Hub.
    output reg         query_valid,
    output reg  [31:0] query_word,
    output reg  [31:0] query_time,
    output reg         st_valid,
    input  wire        st_ready,
    output reg  [15:0] st_len,
    output reg  [31:0] st_time,
    input  wire        st_done,
    output wire [15:0] hub_rd_addr,
    output wire [31:0] hub_rd_time,
    input  wire [31:0] hub_rd_data,
    // Real-time block.
    output reg         rt_sample,
    output reg  [31:0] rt_sample_time,
    output wire [9:0]  rt_index,
    input  wire [15:0] rt_addr,       // the register holding that quadlet
    input  wire        rt_stamp,      // ... or the timestamp
    input  wire        rt_zero,       // ... or 0
    input  wire [31:0] rt_extra,      // ... or'ed with this
    input  wire [31:0] rt_timestamp,
    // Command slicer.
    output reg         sl_start,
    output reg  [15:0] sl_len,
    output reg  [31:0] sl_time,
    input  wire        sl_busy,
    input  wire [8:0]  sl_rd_addr,
    input  wire        sl_wr_en,
    input  wire [15:0] sl_wr_addr,
    input  wire [31:0] sl_wr_data,
    input  wire [31:0] sl_wr_time,
    input  wire [8:0]  hub_src_addr,
    // Reply to link_ctrl.
    output reg         reply_valid,
    output reg  [1:0]  reply_kind,
    output reg  [3:0]  reply_ack,
    output reg  [31:0] reply_h0, reply_h1, reply_h2, reply_h3,
    output reg  [9:0]  reply_data_quads,
    // Payload port (framer).
    input  wire        pl_rd,
    input  wire [9:0]  pl_index,
    input  wire        pl_snapshot,   // the broadcast is going out
    input  wire [31:0] snap_rd_data,
    output wire [5:0]  snap_rd_addr,
    output wire [31:0] pl_data
);
    localparam [3:0] TC_WQ = 4'h0, TC_WB = 4'h1, TC_WRESP = 4'h2, TC_RQ = 4'h4,
                     TC_RB = 4'h5, TC_RQRESP = 4'h6, TC_RBRESP = 4'h7,
                     TC_LOCKRESP = 4'hB;
    localparam [3:0] ACK_COMPLETE = 4'h1, ACK_PENDING = 4'h2,
                     ACK_DATA_ERROR = 4'hD;
    localparam [3:0] RC_COMPLETE = 4'h0, RC_TYPE_ERROR = 4'h6,
                     RC_ADDRESS_ERROR = 4'h7;
    localparam [1:0] K_NONE = 2'd0, K_ACK = 2'd1, K_RESP = 2'd2;
    localparam [3:0] S_IDLE = 4'd0, S_DECIDE = 4'd1, S_RQ_DATA = 4'd2,
                     S_BLKWR = 4'd3, S_QUERY_RD = 4'd4, S_STORE = 4'd5,
                     S_SLICE = 4'd6, S_QUERY_TAKE = 4'd7, S_RQ_WAIT = 4'd8;
    localparam [1:0] P_RT = 2'd0, P_ADDR = 2'd1;

    reg  [3:0]  state;
    // q0's rt and pri fields are not used.
    /* verilator lint_off UNUSEDSIGNAL */
    reg  [31:0] q0;
    /* verilator lint_on UNUSEDSIGNAL */
    reg  [31:16] q1;          // source (the offset's bits are compared on taking)
    reg  [15:0]  q2;          // offset bits 15:0
    reg  [31:0]  q3;
    reg         hdr_ok, has_data, data_ok, len_ok, slot, early;
    reg  [31:0] t;
    reg         dropped;      // a packet answered busy still to be skipped

    // ---- header fields -----------------------------------------------------
    wire [5:0]  tl      = q0[15:10];
    wire [3:0]  tcode   = q0[7:4];
    wire [15:0] source  = q1[31:16];
    wire [15:0] addr16  = q2[15:0];
    wire [15:0] dlen    = q3[31:16];
    // The comparisons of the header's fields, made as the packet is taken
    // (registered with it, so that the decision is a clock of its own).
    reg         f_to_me, f_bcast, f_dest0, f_cmd_offset;
    reg         f_main, f_hub_mem, f_hub_space, f_query, f_addr0;
    reg  [3:0]  f_rb_rcode;
    function [3:0] block_read_rcode(input [15:0] length);
        block_read_rcode = (length == 16'd0 || length[1:0] != 2'd0) ? RC_TYPE_ERROR :
                           (length > 16'd2048) ? RC_ADDRESS_ERROR : RC_COMPLETE;
    endfunction
    // Only the physical ID is compared, not the bus ID (FireWire.v l.891).
    wire        to_me   = f_to_me;
    wire        bcast   = f_bcast;
    wire        node0   = !to_me && f_dest0;
    wire        taken   = len_ok && hdr_ok && (to_me || bcast || node0);
    // A request for this node whose header CRC fails: ack_data_error, no
    // response, no effect (FireWire.v l.1090).
    wire        is_request = (tcode == TC_WQ) || (tcode == TC_WB) ||
                             (tcode == TC_RQ) || (tcode == TC_RB);
    wire        hdr_bad_for_me = len_ok && !hdr_ok && to_me && is_request;
    wire        is_main    = f_main;
    wire        is_hub_mem = f_hub_mem;
    wire        is_query   = f_query;

    wire wq_taken = taken && tcode == TC_WQ && !(node0 && !is_query);
    wire wb_taken = taken && tcode == TC_WB &&
                    !(node0 && !f_cmd_offset);
    wire wb_bad   = wb_taken && has_data && !data_ok;

    // Response headers.
    wire [31:0] resp_h1 = {10'h3FF, phy_id, 16'd0};
    wire [3:0]  rb_rcode = f_rb_rcode;

    // ---- payload port ------------------------------------------------------
    reg  [1:0]  pl_src;
    reg  [15:0] pl_base;
    reg  [31:0] pl_time;
    // Four stages from the framer's request (its pl_rd, pl_index are
    // registers) to the word on pl_data:
    // 1. the addresses are worked out (base + index, or the real-time
    //    block's register for the index) and registered;
    // 2. the register file and the block RAMs (hub memory, snapshot) take
    //    them;
    // 3. the register word is completed (real-time block: timestamp,
    //    zeros, buffer status) and registered; the block RAMs register
    //    theirs once more;
    // 4. pl_data selects the word.
    reg         p1_valid, p1_snapshot, p1_rt, p1_hub;
    reg  [15:0] p1_addr;        // base + index (hub address)
    reg  [5:0]  p1_index;       // snapshot quadlet
    reg  [15:0] p1_regs_addr;   // the register read for it
    reg         p1_stamp, p1_zero;
    reg  [31:0] p1_extra;
    reg  [1:0]  p2_sel;     // 0 real-time, 1 registers, 2 hub, 3 snapshot
    reg         p2_stamp, p2_zero;
    reg  [31:0] p2_extra;
    reg  [1:0]  p3_sel;
    reg  [31:0] p3_word;
    wire [15:0] next_addr = pl_base + {6'd0, pl_index};
    reg  [15:0] rq_addr;
    reg         rq_read;
    always @(posedge clk) begin
        p1_valid     <= pl_rd;
        p1_snapshot  <= pl_snapshot;
        p1_rt        <= (pl_src == P_RT);
        p1_hub       <= (next_addr[15:12] == 4'h1);
        p1_addr      <= next_addr;
        p1_index     <= pl_index[5:0];
        // The register file's address is always this register: a payload
        // read's, else the quadlet read's (a clock after the packet is
        // taken, with its strobe).
        p1_regs_addr <= !(pl_rd && !pl_snapshot) ? rq_addr :
                        (pl_src == P_RT) ? rt_addr : next_addr;
        p1_stamp     <= rt_stamp;
        p1_zero      <= rt_zero;
        p1_extra     <= rt_extra;
        if (p1_snapshot)   p2_sel <= 2'd3;
        else if (p1_rt)    p2_sel <= 2'd0;
        else if (p1_hub)   p2_sel <= 2'd2;
        else               p2_sel <= 2'd1;
        p2_stamp     <= p1_rt && p1_stamp;
        p2_zero      <= p1_rt && p1_zero;
        p2_extra     <= p1_rt ? p1_extra : 32'd0;
        p3_sel       <= p2_sel;
        p3_word      <= p2_stamp ? rt_timestamp :
                        (p2_zero ? 32'd0 : regs_rd_data | p2_extra);
    end
    assign pl_data       = (p3_sel == 2'd3) ? snap_rd_data :
                           (p3_sel == 2'd2) ? hub_rd_data : p3_word;
    assign snap_rd_addr  = p1_index;
    assign rt_index      = pl_index;
    wire   payload_read     = p1_valid && !p1_snapshot;
    wire   payload_reg_read = payload_read && !p1_rt;
    assign regs_rd_addr  = p1_regs_addr;
    assign regs_rd_strobe = (payload_reg_read && !p1_hub) || rq_read;
    assign hub_rd_addr   = payload_reg_read ? p1_addr : rq_addr;
    assign hub_rd_time   = pl_time;

    // ---- receive buffer read mux -------------------------------------------
    reg [9:0] blk_k;        // next quadlet to read (S_BLKWR)
    reg [9:0] blk_n;
    reg       blk_d;        // a quadlet read last clock
    reg [9:0] blk_kd;
    reg       blk_d2;       // ... two clocks ago: its data is here
    reg [9:0] blk_kd2;
    always @* begin
        case (state)
            S_SLICE:  rxb_addr = {slot, sl_rd_addr};
            S_STORE:  rxb_addr = {slot, hub_src_addr};
            S_BLKWR:  rxb_addr = {slot, blk_k[8:0]};
            default:  rxb_addr = {slot, 9'd0};
        endcase
    end

    assign pkt_ready = (state == S_IDLE) && !snap_busy;

    always @(posedge clk) begin
        reply_valid <= 1'b0;
        refresh     <= 1'b0;
        query_valid <= 1'b0;
        rt_sample   <= 1'b0;
        sl_start    <= 1'b0;
        wr_en       <= 1'b0;
        rq_read     <= 1'b0;
        if (rst) begin
            state <= S_IDLE;
            q0 <= 32'd0; q1 <= 16'd0; q2 <= 16'd0; q3 <= 32'd0;
            hdr_ok <= 1'b0; has_data <= 1'b0; data_ok <= 1'b0; len_ok <= 1'b0;
            slot <= 1'b0; early <= 1'b0; t <= 32'd0; dropped <= 1'b0;
            st_valid <= 1'b0;
            pl_src <= P_RT; pl_base <= 16'd0; pl_time <= 32'd0;
            rq_addr <= 16'd0;
            f_to_me <= 1'b0; f_bcast <= 1'b0; f_dest0 <= 1'b0; f_cmd_offset <= 1'b0;
            f_main <= 1'b0; f_hub_mem <= 1'b0; f_hub_space <= 1'b0; f_query <= 1'b0;
            f_addr0 <= 1'b0; f_rb_rcode <= RC_COMPLETE;
            blk_k <= 10'd0; blk_n <= 10'd0; blk_d <= 1'b0; blk_kd <= 10'd0;
            blk_d2 <= 1'b0; blk_kd2 <= 10'd0;
            reply_kind <= K_NONE; reply_ack <= 4'd0; reply_data_quads <= 10'd0;
            reply_h0 <= 32'd0; reply_h1 <= 32'd0; reply_h2 <= 32'd0; reply_h3 <= 32'd0;
            wr_addr <= 16'd0; wr_data <= 32'd0; wr_time <= 32'd0;
            refresh_time <= 32'd0; query_word <= 32'd0; query_time <= 32'd0;
            st_len <= 16'd0; st_time <= 32'd0; rt_sample_time <= 32'd0;
            sl_len <= 16'd0; sl_time <= 32'd0;
        end else begin
            // The slicer's writes pass through.
            if (sl_wr_en) begin
                wr_en   <= 1'b1;
                wr_addr <= sl_wr_addr;
                wr_data <= sl_wr_data;
                wr_time <= sl_wr_time;
            end
            if (drop_early) dropped <= 1'b1;
            case (state)
                S_IDLE: if (pkt_valid && pkt_ready && pkt_early && (dropped || drop_early)) begin
                    dropped <= 1'b0;           // answered busy: no effect
                end else if (pkt_valid && pkt_ready) begin
                    q0 <= pkt_q0; q1 <= pkt_q1[31:16]; q2 <= pkt_q2[15:0]; q3 <= pkt_q3;
                    hdr_ok <= pkt_hdr_ok; has_data <= pkt_has_data;
                    data_ok <= pkt_data_ok; len_ok <= pkt_len_ok;
                    slot <= pkt_slot; early <= pkt_early; t <= pkt_time;
                    rq_addr <= pkt_q2[15:0];
                    pl_time <= pkt_time;
                    f_to_me      <= phy_id_valid && (pkt_q0[21:16] == phy_id);
                    f_bcast      <= (pkt_q0[21:16] == 6'h3F);
                    f_dest0      <= (pkt_q0[21:16] == 6'd0);
                    f_cmd_offset <= ({pkt_q1[15:0], pkt_q2} == 48'hFFFF_FFFF_0000);
                    f_main       <= (pkt_q2[15:8] == 8'h00);
                    f_hub_mem    <= (pkt_q2[15:12] == 4'h1) && (pkt_q2[11:0] < 12'h200);
                    f_hub_space  <= (pkt_q2[15:12] == 4'h1);
                    f_query      <= (pkt_q2[15:0] == 16'h1800);
                    f_addr0      <= (pkt_q2[15:0] == 16'd0);
                    f_rb_rcode   <= block_read_rcode(pkt_q3[31:16]);
                    state <= S_DECIDE;
                end
                S_DECIDE: begin
                    state <= S_IDLE;
                    // The reply (only to packets the link asked a grant for).
                    // The reply registers change only for packets the link
                    // asked a grant for (they are read when it comes).
                    reply_valid <= early;
                    if (early) begin
                        reply_kind <= K_NONE;
                        reply_h0 <= {source, tl, 2'b00, TC_RQRESP, 4'h0};
                        reply_h1 <= resp_h1;
                        reply_h2 <= 32'd0;
                        reply_h3 <= 32'd0;
                        reply_data_quads <= 10'd0;
                    end
                    if (taken && to_me && early) begin
                        case (tcode)
                            TC_WQ: begin reply_kind <= K_ACK; reply_ack <= ACK_COMPLETE; end
                            TC_WB: begin
                                reply_kind <= K_ACK;
                                reply_ack  <= wb_bad ? ACK_DATA_ERROR : ACK_COMPLETE;
                            end
                            TC_RQ: begin
                                reply_kind <= K_RESP;
                                reply_ack  <= ACK_PENDING;
                            end
                            TC_RB: begin
                                reply_kind <= K_RESP;
                                reply_ack  <= ACK_PENDING;
                                reply_h0   <= {source, tl, 2'b00, TC_RBRESP, 4'h0};
                                reply_h1   <= {10'h3FF, phy_id, rb_rcode, 12'd0};
                                reply_h3   <= {(rb_rcode == RC_COMPLETE) ? dlen : 16'd0, 16'd0};
                                reply_data_quads <= (rb_rcode == RC_COMPLETE) ? dlen[11:2] : 10'd0;
                            end
                            TC_WRESP, TC_RQRESP, TC_RBRESP, TC_LOCKRESP: begin
                                reply_kind <= K_ACK; reply_ack <= ACK_COMPLETE;
                            end
                            // A lock request gets no ack (FireWire.v l.893-919).
                            default: ;
                        endcase
                    end
                    if (hdr_bad_for_me && early) begin
                        reply_kind <= K_ACK;
                        reply_ack  <= ACK_DATA_ERROR;
                    end
                    // Reads.
                    if (taken && to_me && tcode == TC_RQ) begin
                        // The quadlet comes from the register file's or
                        // the hub's read port, two clocks on.
                        reply_valid <= 1'b0;
                        state       <= S_RQ_WAIT;
                        if (!f_hub_space) rq_read <= 1'b1;
                    end
                    if (taken && to_me && tcode == TC_RB && rb_rcode == RC_COMPLETE) begin
                        pl_base <= addr16;
                        if (f_addr0) begin
                            pl_src         <= P_RT;
                            rt_sample      <= 1'b1;
                            rt_sample_time <= t;
                        end else begin
                            pl_src <= P_ADDR;
                        end
                    end
                    // Writes.
                    if (wq_taken) begin
                        refresh      <= 1'b1;
                        refresh_time <= t;
                        if (is_query) begin
                            query_valid <= 1'b1;
                            query_word  <= q3;
                            query_time  <= t;
                        end else begin
                            wr_en   <= 1'b1;
                            wr_addr <= addr16;
                            wr_data <= q3;
                            wr_time <= t;
                        end
                    end
                    if (wb_taken && !wb_bad) begin
                        refresh      <= 1'b1;
                        refresh_time <= t;
                        if (f_addr0) begin
                            sl_start <= 1'b1;
                            sl_len   <= has_data ? dlen : 16'd0;
                            sl_time  <= t;
                            state    <= S_SLICE;
                        end else if (is_hub_mem) begin
                            st_valid <= 1'b1;
                            st_len   <= has_data ? dlen : 16'd0;
                            st_time  <= t;
                            state    <= S_STORE;
                        end else if (is_query) begin
                            if (has_data && dlen >= 16'd4) state <= S_QUERY_RD;
                        end else if (is_main && has_data) begin
                            blk_k <= 10'd0;
                            blk_n <= (dlen[15:11] != 5'd0) ? 10'd512 : {1'b0, dlen[10:2]};
                            blk_d <= 1'b0;
                            blk_d2 <= 1'b0;
                            state <= S_BLKWR;
                        end
                    end
                end
                S_RQ_WAIT: state <= S_RQ_DATA;  // the ports read rq_addr
                S_RQ_DATA: begin
                    // hub_rd_data and regs_rd_data answer rq_addr now.
                    reply_valid <= early;
                    reply_h3    <= f_hub_space ? hub_rd_data : regs_rd_data;
                    state       <= S_IDLE;
                end
                // A query in the first quadlet of a block write: the buffer
                // reads quadlet 0 (address set since the decision), its data
                // is there two clocks later.
                S_QUERY_RD: state <= S_QUERY_TAKE;
                S_QUERY_TAKE: begin
                    query_valid <= 1'b1;
                    query_word  <= rxb_data;
                    query_time  <= t;
                    state       <= S_IDLE;
                end
                S_STORE: begin
                    if (st_valid && st_ready) st_valid <= 1'b0;
                    if (st_done) state <= S_IDLE;
                end
                S_SLICE: if (!sl_start && !sl_busy) state <= S_IDLE;
                S_BLKWR: begin
                    blk_d   <= (blk_k < blk_n);
                    blk_kd  <= blk_k;
                    blk_d2  <= blk_d;
                    blk_kd2 <= blk_kd;
                    if (blk_k < blk_n) blk_k <= blk_k + 10'd1;
                    if (blk_d2) begin
                        wr_en   <= 1'b1;
                        wr_addr <= addr16 + {6'd0, blk_kd2};
                        wr_data <= rxb_data;
                        wr_time <= t;
                    end
                    if (!blk_d && !blk_d2 && blk_k >= blk_n) state <= S_IDLE;
                end
                default: state <= S_IDLE;
            endcase
        end
    end
endmodule

`default_nettype wire
