// broadcast_hub: the hub side of the broadcast protocol
// (shared/spec/fpga-board.md, section 6): the query register, the hub
// memory every board fills with every board's status broadcast, and the
// hub registers.
//
// - A query (write of seq<<16 | mask to 0x1800, seq != 0) starts a cycle:
//   the memory is refilled from its start, no board has been heard yet.
//   A word with sequence 0 is ignored.
// - A status broadcast (a block write into 0x1000-0x11FF: header
//   seq<<16 | size, then the real-time block) is stored in arrival order
//   with its header rewritten as Rev 8 does: size:8 | seq_low:8 |
//   seq_error:1 | update_time:15 (clocks since the query, saturated). A
//   payload whose size field does not match its length, that is not whole
//   quadlets, or that does not fit in the 512 quadlets is not stored. The
//   board named by its STATUS quadlet counts as heard; once every board of
//   the query's mask has been heard a timing quadlet follows the last entry.
// - This board's own broadcast is stored the same way when it has gone out
//   (own_valid), unless a new query came first.
// - Reads: 0x1000 + i memory quadlet i, except the timing quadlet, which
//   reads read_start:16 | now:16 = clocks from the query to the read, and
//   to the moment that quadlet leaves in a response (4 clocks per quadlet
//   at S400 after the 5-quadlet response header); 0x1800 the query,
//   0x1802 the quadlets written; anything else 0. Read data follows the
//   address by two clocks (the memory's output is registered).
// Stores copy from a source RAM (receive buffer or the broadcast snapshot)
// whose data follows src_addr by two clocks; the packet was checked
// (header and data CRC) before a store is asked for.
`default_nettype none

module broadcast_hub (
    input  wire        clk,
    input  wire        rst,
    input  wire        reboot,
    // Query.
    input  wire        query_valid,
    input  wire [31:0] query_word,
    input  wire [31:0] query_time,
    output reg         query_event,     // a query was taken
    output reg  [31:0] query_reg,       // 0: none since power-up
    output reg  [31:0] query_at,
    // Store of a received broadcast.
    input  wire        st_valid,
    output wire        st_ready,
    input  wire [15:0] st_len,          // bytes
    input  wire [31:0] st_time,
    output reg         st_done,
    // Store of this board's own broadcast (snapshot source).
    input  wire        own_valid,
    input  wire [31:0] own_time,
    // Source RAM.
    output reg  [8:0]  src_addr,
    output reg         src_sel,         // 0 receive buffer, 1 snapshot
    output wire        src_active,      // a store is reading the source
    input  wire [31:0] src_data,
    // Boards heard this cycle.
    output reg  [15:0] seen,
    output reg         seen_event,
    output reg  [31:0] seen_time,
    // Read port.
    input  wire [15:0] rd_addr,
    input  wire [31:0] rd_time,
    output wire [31:0] rd_data
);
    localparam [3:0] S_IDLE = 4'd0, S_HDR = 4'd1, S_CHECK = 4'd2, S_COPY = 4'd3,
                     S_DRAIN = 4'd4, S_FINISH = 4'd5, S_CLEAR = 4'd6, S_LATCH = 4'd7,
                     S_HDR2 = 4'd8, S_DRAIN2 = 4'd9;
    localparam [15:0] OWN_LEN = 16'd132;   // header + 32 quadlets

    reg  [3:0]  state;
    reg  [9:0]  count;          // quadlets written (0..512)
    reg         timing_valid;
    reg  [8:0]  timing_index;
    reg         complete;
    reg         own_pending;
    reg  [31:0] own_at;
    reg  [15:0] len;
    reg  [31:0] t_store;
    reg  [9:0]  nq;             // entry quadlets
    reg  [9:0]  k;              // next source quadlet to read
    reg  [9:0]  w;              // next quadlet to write
    reg  [3:0]  board;
    // The header quadlet and its checks, registered before they are acted
    // on.
    reg  [15:0] hdr_seq;
    reg  [9:0]  hdr_size;      // quadlets (checked <= 255)
    reg         hdr_bad, hdr_long;

    // Hub memory.
    reg         mem_we;
    reg  [8:0]  mem_waddr;
    reg  [31:0] mem_wdata;
    wire [31:0] mem_rdata;
    sdp_ram #(.WIDTH(32), .DEPTH(512), .ADDR_BITS(9), .OUT_REG(1)) memory (
        .clk(clk), .wr_en(mem_we), .wr_addr(mem_waddr), .wr_data(mem_wdata),
        .rd_addr(rd_addr[8:0]), .rd_data(mem_rdata));

    // Read port: the address registered, then the selection registered
    // beside the memory's second read register.
    reg  [15:0] rd_addr_q;
    always @(posedge clk) rd_addr_q <= rd_addr;
    wire [11:0] rd_index = rd_addr_q[11:0];
    reg        rd_is_mem, rd_is_timing;
    reg [31:0] rd_other, rd_timing;
    // Clocks from the query to the read's packet, registered (both change
    // only when a packet is taken, long before its reads).
    reg  [31:0] start;
    always @(posedge clk) start <= rd_time - query_at;
    wire [31:0] leaving = start + {21'd0, rd_index[8:0], 2'b00} + 32'd20;
    function [15:0] sat16(input [31:0] v);
        sat16 = (v[31:16] != 16'd0) ? 16'hFFFF : v[15:0];
    endfunction
    always @(posedge clk) begin
        rd_is_mem    <= (rd_addr_q[15:12] == 4'h1) && (rd_index < 12'h200);
        rd_is_timing <= (rd_addr_q[15:12] == 4'h1) && timing_valid &&
                        (rd_index == {3'd0, timing_index});
        rd_timing    <= {sat16(start), sat16(leaving)};
        if (rd_addr_q == 16'h1800)      rd_other <= query_reg;
        else if (rd_addr_q == 16'h1802) rd_other <= {22'd0, count};
        else                          rd_other <= 32'd0;
    end
    assign rd_data = rd_is_timing ? rd_timing : (rd_is_mem ? mem_rdata : rd_other);

    assign st_ready   = (state == S_IDLE) && !own_pending;
    assign src_active = (state != S_IDLE) && (state != S_CLEAR);

    // Header rewrite (Rev 8).
    wire [15:0] src_size = src_data[15:0];
    wire [15:0] b_seq  = hdr_seq;
    wire [9:0]  b_size = hdr_size;
    wire [31:0] upd    = t_store - query_at;
    wire [14:0] upd15  = (query_reg == 32'd0) ? 15'd0 :
                         ((upd[31:15] != 17'd0) ? 15'h7FFF : upd[14:0]);
    wire [15:0] q_seq  = query_reg[31:16];
    wire [31:0] rewritten = {b_size[7:0], b_seq[7:0], (b_seq != q_seq), upd15};
    wire [31:0] done_clocks = t_store - query_at;
    wire [15:0] mask   = query_reg[15:0];
    wire [15:0] seen_after = seen | (16'd1 << board);

    always @(posedge clk) begin
        st_done     <= 1'b0;
        seen_event  <= 1'b0;
        query_event <= 1'b0;
        mem_we      <= 1'b0;
        if (rst) begin
            state        <= S_IDLE;
            count        <= 10'd0;
            timing_valid <= 1'b0;
            timing_index <= 9'd0;
            complete     <= 1'b0;
            own_pending  <= 1'b0;
            own_at       <= 32'd0;
            query_reg    <= 32'd0;
            query_at     <= 32'd0;
            seen         <= 16'd0;
            seen_time    <= 32'd0;
            src_addr     <= 9'd0;
            src_sel      <= 1'b0;
            len <= 16'd0; t_store <= 32'd0; nq <= 10'd0; k <= 10'd0; w <= 10'd0;
            board <= 4'd0;
            hdr_seq <= 16'd0; hdr_size <= 10'd0;
            hdr_bad <= 1'b0; hdr_long <= 1'b0;
        end else if (reboot) begin
            // Back to power-up: the memory is cleared quadlet by quadlet.
            state        <= S_CLEAR;
            w            <= 10'd0;
            count        <= 10'd0;
            timing_valid <= 1'b0;
            complete     <= 1'b0;
            own_pending  <= 1'b0;
            query_reg    <= 32'd0;
            query_at     <= 32'd0;
            seen         <= 16'd0;
        end else begin
            if (own_valid) begin
                own_pending <= 1'b1;
                own_at      <= own_time;
            end
            if (query_valid && query_word[31:16] != 16'd0) begin
                query_event  <= 1'b1;
                query_reg    <= query_word;
                query_at     <= query_time;
                count        <= 10'd0;
                seen         <= 16'd0;
                complete     <= 1'b0;
                timing_valid <= 1'b0;
                own_pending  <= 1'b0;
            end
            case (state)
                S_IDLE: begin
                    if (own_pending && !own_valid && !query_valid) begin
                        own_pending <= 1'b0;
                        src_sel  <= 1'b1;
                        len      <= OWN_LEN;
                        t_store  <= own_at;
                        src_addr <= 9'd0;
                        state    <= S_HDR;
                    end else if (st_valid && !own_pending && !query_valid) begin
                        src_sel  <= 1'b0;
                        len      <= st_len;
                        t_store  <= st_time;
                        src_addr <= 9'd0;
                        state    <= S_HDR;
                    end
                end
                S_HDR:  state <= S_HDR2;
                S_HDR2: state <= S_LATCH;  // header quadlet on src_data next
                S_LATCH: begin
                    // Whole quadlets, size matches, fits (size <= 255 for
                    // Rev 8): checked here, acted on next clock.
                    hdr_seq  <= src_data[31:16];
                    hdr_size <= src_size[9:0];
                    hdr_bad  <= len < 16'd4 || len[1:0] != 2'd0 ||
                                {src_size, 2'b00} != {2'b00, len} ||
                                src_size > 16'd255 || {6'd0, count} + src_size > 16'd512;
                    hdr_long <= src_size > 16'd1;
                    state    <= S_CHECK;
                end
                S_CHECK: begin
                    if (hdr_bad) begin
                        if (!src_sel) st_done <= 1'b1;
                        state <= S_IDLE;
                    end else begin
                        nq        <= b_size[9:0];
                        mem_we    <= 1'b1;
                        mem_waddr <= count[8:0];
                        mem_wdata <= rewritten;
                        board     <= 4'd0;
                        w         <= 10'd1;
                        k         <= 10'd1;
                        if (hdr_long) begin
                            src_addr <= 9'd1;
                            k        <= 10'd2;
                            state    <= S_DRAIN2;
                        end else begin
                            state <= S_FINISH;
                        end
                    end
                end
                S_DRAIN2, S_DRAIN: begin
                    // Three reads in flight (address register, the RAM's
                    // two read registers).
                    if (k < nq) begin
                        src_addr <= k[8:0];
                        k        <= k + 10'd1;
                    end
                    state <= (state == S_DRAIN2) ? S_DRAIN : S_COPY;
                end
                S_COPY: begin
                    // Quadlet w is on src_data; ask for quadlet k.
                    mem_we    <= 1'b1;
                    mem_waddr <= count[8:0] + w[8:0];
                    mem_wdata <= src_data;
                    if (w == 10'd2) begin
                        // The STATUS quadlet names the board: heard now
                        // (the store can no longer fail), so the chain's
                        // next board learns it within a few clocks.
                        board      <= src_data[27:24];
                        seen       <= seen | (16'd1 << src_data[27:24]);
                        seen_event <= 1'b1;
                        seen_time  <= t_store;
                    end
                    w <= w + 10'd1;
                    if (k < nq) begin
                        src_addr <= k[8:0];
                        k        <= k + 10'd1;
                    end
                    if (w + 10'd1 == nq) state <= S_FINISH;
                end
                S_FINISH: begin
                    count      <= count + nq;
                    if (nq < 10'd3) begin
                        // Too short to name a board: counts as board 0.
                        seen       <= seen_after;
                        seen_event <= 1'b1;
                        seen_time  <= t_store;
                    end
                    if (!src_sel) st_done <= 1'b1;
                    state <= S_IDLE;
                    if (!complete && mask != 16'd0 && (mask & ~seen_after) == 16'd0) begin
                        complete <= 1'b1;
                        if (count + nq < 10'd512) begin
                            mem_we       <= 1'b1;
                            mem_waddr    <= count[8:0] + nq[8:0];
                            mem_wdata    <= {16'd0, sat16(done_clocks)};
                            timing_valid <= 1'b1;
                            timing_index <= count[8:0] + nq[8:0];
                            count        <= count + nq + 10'd1;
                        end
                    end
                end
                S_CLEAR: begin
                    mem_we    <= 1'b1;
                    mem_waddr <= w[8:0];
                    mem_wdata <= 32'd0;
                    w         <= w + 10'd1;
                    if (w == 10'd511) state <= S_IDLE;
                end
                default: state <= S_IDLE;
            endcase
            // A query during a store: the entry being stored belongs to the
            // old cycle and is abandoned.
            if (query_valid && query_word[31:16] != 16'd0 && state != S_IDLE &&
                state != S_CLEAR) begin
                if (!src_sel) st_done <= 1'b1;
                state <= S_IDLE;
            end
        end
    end
endmodule

`default_nettype wire
