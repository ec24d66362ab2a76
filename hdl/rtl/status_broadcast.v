// status_broadcast: when and what this board broadcasts after a query
// (shared/spec/fpga-board.md, section 6.2; seed 000).
//
// On a query the real-time block is sampled at the query's clock and a
// snapshot of the broadcast payload (header seq<<16 | 33, then the 32
// quadlets) is kept. The slot:
// - chain (firmware Rev 7+, CHAIN = 1): only boards selected by the
//   query's mask answer. The lowest selected board may go FIRST_SLOT clocks
//   after the query; each other board as soon as every lower selected board
//   has been heard (and not before FIRST_SLOT), or, if some stay silent,
//   CHAIN_TIMEOUT clocks per missing lower board after FIRST_SLOT.
// - TDMA (seed 000, CHAIN = 0): every board answers, TDMA_OFFSET +
//   TDMA_SLOT x physical ID clocks after the query.
// The request for the bus (an isochronous-style request: seed 000's bus
// arbitration acceleration) goes to the PHY REQUEST_DELAY clocks after the
// slot instant, a fixed pipeline delay that covers the time the hub takes
// to store a received broadcast, so the instant itself is exact to the
// clock. A bus reset, a reboot or a new query drops a broadcast not yet
// sent.
`default_nettype none

module status_broadcast #(
    parameter [3:0]  BOARD_ID      = 4'd0,
    parameter        CHAIN         = 1'b1,
    parameter [31:0] FIRST_SLOT    = 32'd150,   // ~3.05 us
    parameter [31:0] CHAIN_TIMEOUT = 32'd2458,  // ~50 us per silent board
    parameter [31:0] TDMA_OFFSET   = 32'd150,   // ~3.05 us
    parameter [31:0] TDMA_SLOT     = 32'd256,   // ~5.21 us per node
    parameter [31:0] REQUEST_DELAY = 32'd16     // clocks
) (
    input  wire        clk,
    input  wire        rst,
    input  wire [31:0] now,
    input  wire [5:0]  phy_id,
    input  wire        phy_id_valid,
    input  wire        bus_reset,
    input  wire        reboot,        // STATUS reboot: nothing waits any more
    // From the hub.
    input  wire        query_event,
    input  wire [31:0] query_reg,
    input  wire [31:0] query_at,
    input  wire [15:0] seen,
    input  wire        seen_event,
    input  wire [31:0] seen_time,
    // Real-time block.
    output reg         rt_sample,
    output reg  [31:0] rt_sample_time,
    output reg  [9:0]  rt_index,
    input  wire [31:0] rt_data,       // for rt_index two clocks ago
    // Snapshot RAM write port.
    output reg         snap_we,
    output reg  [5:0]  snap_waddr,
    output reg  [31:0] snap_wdata,
    output wire        snap_busy,
    // To the link.
    output reg         bc_req,        // a broadcast is waiting for the bus
    input  wire        bc_sent        // it went out
);
    initial begin
        if (REQUEST_DELAY < 8) begin
            $display("status_broadcast: REQUEST_DELAY must cover the hub (>= 8)");
            $finish;
        end
    end

    localparam [15:0] BLOCK_QUADLETS = 16'd33;

    reg        pending;
    reg [15:0] wait_for;
    reg        all_seen;
    reg [31:0] earliest, seen_done;
    // The same instants + REQUEST_DELAY: when the request goes to the PHY.
    reg [31:0] earliest_req, seen_req;
    reg [31:0] deadline_base;   // the chain's deadline before the timeouts (+ REQUEST_DELAY)
    reg [6:0]  copy;          // 0: idle, else next snapshot index + 1
    reg [15:0] seq;

    assign snap_busy = (copy != 7'd0) || rt_sample;

    wire [15:0] mask     = query_reg[15:0];
    wire        selected = mask[BOARD_ID];
    wire [15:0] lower    = mask & ((16'd1 << BOARD_ID) - 16'd1);
    function [4:0] popcount(input [15:0] v);
        integer b;
        begin
            popcount = 5'd0;
            for (b = 0; b < 16; b = b + 1) popcount = popcount + {4'd0, v[b]};
        end
    endfunction

    // The chain's deadline (+ REQUEST_DELAY): CHAIN_TIMEOUT per lower
    // selected board after the first slot, worked out over three registers from the query (the
    // snapshot copy holds the request back for longer).
    reg  [4:0]  lower_count;
    reg  [31:0] lower_timeout, deadline;
    always @(posedge clk) begin
        lower_count   <= popcount(lower);
        lower_timeout <= CHAIN_TIMEOUT * {27'd0, lower_count};
        deadline      <= deadline_base + lower_timeout;
    end

    // The slot instant (as its request instant, + REQUEST_DELAY).
    wire        too_soon = $signed(seen_done - earliest) < 0;
    wire [31:0] slot_req = CHAIN ? (all_seen ? (too_soon ? earliest_req : seen_req)
                                             : deadline)
                                 : earliest_req;
    // The request's clock, registered: the slot's inputs settle at least
    // REQUEST_DELAY clocks before it (the hub stores a broadcast within
    // that), and the snapshot copy (34 clocks) holds the request back
    // after a query, so `due` never sees a stale value.
    reg  [31:0] request_at;
    always @(posedge clk) request_at <= slot_req;
    wire        due     = $signed(now - request_at) >= 0;
    wire        heard_all_now = ((wait_for & ~seen) == 16'd0);

    always @(posedge clk) begin
        rt_sample <= 1'b0;
        snap_we   <= 1'b0;
        if (rst || bus_reset || reboot) begin
            pending  <= 1'b0;
            bc_req   <= 1'b0;
            copy     <= 7'd0;
            if (rst) begin
                wait_for  <= 16'd0;
                all_seen  <= 1'b0;
                earliest  <= 32'd0;
                earliest_req <= 32'd0;
                seen_req  <= 32'd0;
                deadline_base <= 32'd0;
                seen_done <= 32'd0;
                seq       <= 16'd0;
                rt_index  <= 10'd0;
                rt_sample_time <= 32'd0;
                snap_waddr <= 6'd0;
                snap_wdata <= 32'd0;
            end
        end else if (query_event) begin
            // Sample now; schedule the slot.
            rt_sample      <= 1'b1;
            rt_sample_time <= query_at;
            seq            <= query_reg[31:16];
            copy           <= 7'd1;
            bc_req         <= 1'b0;
            seen_done      <= query_at;
            seen_req       <= query_at + REQUEST_DELAY;
            if (CHAIN) begin
                pending  <= selected;
                wait_for <= lower;
                all_seen <= (lower == 16'd0);
                earliest <= query_at + FIRST_SLOT;
                earliest_req  <= query_at + (FIRST_SLOT + REQUEST_DELAY);
                deadline_base <= query_at + (FIRST_SLOT + REQUEST_DELAY);
            end else begin
                pending  <= phy_id_valid;
                wait_for <= 16'd0;
                all_seen <= 1'b1;
                earliest <= query_at + TDMA_OFFSET + TDMA_SLOT * {26'd0, phy_id};
                earliest_req  <= query_at + (TDMA_OFFSET + REQUEST_DELAY) +
                                 TDMA_SLOT * {26'd0, phy_id};
                deadline_base <= query_at + (TDMA_OFFSET + REQUEST_DELAY) +
                                 TDMA_SLOT * {26'd0, phy_id};
            end
        end else begin
            // Snapshot: header, then block quadlets 0..31 (each read two
            // clocks ahead: the index is registered, then the register
            // file's word).
            if (copy != 7'd0) begin
                rt_index <= {3'd0, copy} - 10'd1;
                if (copy == 7'd1) begin
                    snap_we    <= 1'b1;
                    snap_waddr <= 6'd0;
                    snap_wdata <= {seq, BLOCK_QUADLETS};
                end else if (copy >= 7'd3) begin
                    snap_we    <= 1'b1;
                    snap_waddr <= copy[5:0] - 6'd2;
                    snap_wdata <= rt_data;
                end
                copy <= (copy == 7'd34) ? 7'd0 : copy + 7'd1;
            end
            // Every lower selected board heard: remember when.
            if (pending && !all_seen && seen_event && heard_all_now) begin
                all_seen  <= 1'b1;
                seen_done <= seen_time;
                seen_req  <= seen_time + REQUEST_DELAY;
            end
            if (pending && copy == 7'd0 && due) begin
                pending         <= 1'b0;
                bc_req          <= 1'b1;
            end
            if (bc_sent) bc_req <= 1'b0;
        end
    end
endmodule

`default_nettype wire
