// link_ctrl: who uses the bus next, and what is sent when it is granted.
//
// - An ack: when the first quadlet of a packet names this node the link
//   asks for an immediate grant (the PHY grants right after the packet
//   ends, with no arbitration). When the grant comes, the request handler's
//   reply decides: an ack, an ack followed by the concatenated response
//   (ack_pending + read response, without releasing the bus), or nothing
//   (a header CRC error: the grant is released unused). A handler still
//   busy with an earlier packet REPLY_WAIT clocks after the grant gets
//   ack_busy_X sent for it, and is told to drop that packet (drop_early):
//   the requester will send it again. An immediate
//   request replaces a waiting broadcast request in the PHY; the broadcast
//   is asked for again afterwards.
// - The status broadcast: an isochronous-style request while the
//   broadcaster says one is waiting; when granted, the broadcast block
//   write (header built here, payload from the snapshot); bc_sent pulses
//   when it has gone out.
// A bus reset forgets every request.
`default_nettype none

module link_ctrl (
    input  wire        clk,
    input  wire        rst,
    input  wire        bus_reset,
    input  wire [5:0]  phy_id,
    // Packet for this node begins.
    input  wire        early_for_me,
    // The handler's reply to it.
    input  wire        reply_valid,
    input  wire [1:0]  reply_kind,      // 0 nothing, 1 ack, 2 ack + response
    input  wire [3:0]  reply_ack,
    input  wire [31:0] reply_h0, reply_h1, reply_h2, reply_h3,
    input  wire [9:0]  reply_data_quads,
    // Status broadcast.
    input  wire        bc_req,
    output reg         bc_sent,
    output reg         drop_early,      // the packet was answered busy: drop it
    output reg         bc_active,       // the payload comes from the snapshot
    // PHY-link interface.
    output reg         busreq_valid,
    input  wire        busreq_ready,
    output reg  [2:0]  busreq_type,
    input  wire        grant,
    output reg         cancel,
    input  wire        tx_done,
    // Framer.
    output reg         job_valid,
    input  wire        job_ready,
    output reg         job_ack,
    output reg  [3:0]  job_ack_code,
    output reg         job_pkt,
    output wire [31:0] job_h0, job_h1, job_h2, job_h3,
    output reg  [2:0]  job_hdr_quads,
    output reg  [9:0]  job_data_quads
);
    localparam [2:0] REQ_IMM = 3'd0, REQ_ISO = 3'd1;
    localparam [1:0] O_NONE = 2'd0, O_IMM = 2'd1, O_ISO = 2'd2;
    localparam [1:0] G_IDLE = 2'd0, G_WAIT_REPLY = 2'd1, G_SENDING = 2'd2;
    localparam [7:0] REPLY_WAIT = 8'd32;
    localparam [3:0] ACK_BUSY_X = 4'h4;

    reg [1:0]  outstanding;   // request the PHY holds
    reg [1:0]  gstate;
    reg        sending_bc;
    reg        want_imm;      // an immediate request still to be issued
    reg        have_reply;
    reg [1:0]  r_kind;
    reg [3:0]  r_ack;
    reg [9:0]  r_dq;
    reg        job_bc;        // the job is the status broadcast
    reg [7:0]  waited;
    reg        bc_wait_drop;  // sent: ignore bc_req until the broadcaster drops it

    // The broadcast's header: block write to broadcast, pri 0xA, to
    // 0xFFFF_FF00_1000 (Rev 8), 33 quadlets.
    wire [31:0] bc_h0 = 32'hFFFF_001A;
    wire [31:0] bc_h1 = {10'h3FF, phy_id, 16'hFFFF};
    wire [31:0] bc_h2 = 32'hFF00_1000;
    wire [31:0] bc_h3 = {16'd132, 16'd0};
    // The reply's header stays in the handler's registers until its next
    // reply (after this one has gone out), so the framer reads it there.
    assign job_h0 = job_bc ? bc_h0 : reply_h0;
    assign job_h1 = job_bc ? bc_h1 : reply_h1;
    assign job_h2 = job_bc ? bc_h2 : reply_h2;
    assign job_h3 = job_bc ? bc_h3 : reply_h3;

    always @(posedge clk) begin
        bc_sent    <= 1'b0;
        cancel     <= 1'b0;
        drop_early <= 1'b0;
        if (job_valid && job_ready) job_valid <= 1'b0;
        if (busreq_valid && busreq_ready) busreq_valid <= 1'b0;
        if (rst || bus_reset) begin
            outstanding  <= O_NONE;
            gstate       <= G_IDLE;
            sending_bc   <= 1'b0;
            bc_active    <= 1'b0;
            want_imm     <= 1'b0;
            have_reply   <= 1'b0;
            busreq_valid <= 1'b0;
            job_valid    <= 1'b0;
            bc_wait_drop <= 1'b0;
            if (rst) begin
                busreq_type <= REQ_IMM;
                r_kind <= 2'd0; r_ack <= 4'd0; r_dq <= 10'd0;
                job_ack <= 1'b0; job_ack_code <= 4'd0; job_pkt <= 1'b0;
                job_bc <= 1'b0;
                job_hdr_quads <= 3'd4; job_data_quads <= 10'd0;
                waited <= 8'd0;
            end
        end else begin
            if (!bc_req) bc_wait_drop <= 1'b0;
            if (early_for_me) begin
                want_imm   <= 1'b1;
                have_reply <= 1'b0;   // a reply now belongs to this packet
            end
            if (reply_valid) begin
                have_reply <= 1'b1;
                r_kind <= reply_kind; r_ack <= reply_ack;
                r_dq <= reply_data_quads;
                // A reply needing an ack without an immediate request out.
                if (reply_kind != 2'd0 && outstanding != O_IMM && !want_imm &&
                    !early_for_me && gstate != G_WAIT_REPLY)
                    want_imm <= 1'b1;
            end
            // Issue requests (the LREQ line takes one at a time).
            if (!busreq_valid && gstate == G_IDLE) begin
                if (want_imm && !early_for_me) begin
                    busreq_valid <= 1'b1;
                    busreq_type  <= REQ_IMM;
                    outstanding  <= O_IMM;
                    want_imm     <= 1'b0;
                end else if (bc_req && !bc_wait_drop && outstanding == O_NONE &&
                             !want_imm && !early_for_me) begin
                    busreq_valid <= 1'b1;
                    busreq_type  <= REQ_ISO;
                    outstanding  <= O_ISO;
                end
            end
            case (gstate)
                G_IDLE: if (grant) begin
                    if (outstanding == O_ISO) begin
                        job_valid      <= 1'b1;
                        job_ack        <= 1'b0;
                        job_pkt        <= 1'b1;
                        job_bc         <= 1'b1;
                        job_hdr_quads  <= 3'd4;
                        job_data_quads <= 10'd33;
                        sending_bc     <= 1'b1;
                        bc_active      <= 1'b1;
                        gstate         <= G_SENDING;
                    end else if (outstanding == O_IMM) begin
                        gstate <= G_WAIT_REPLY;
                        waited <= 8'd0;
                    end else begin
                        cancel <= 1'b1;          // not ours to use
                        gstate <= G_SENDING;
                    end
                end
                G_WAIT_REPLY: begin
                    waited <= waited + 8'd1;
                    if (have_reply || reply_valid) begin
                        have_reply <= 1'b0;
                        if ((reply_valid ? reply_kind : r_kind) == 2'd0) begin
                            cancel <= 1'b1;
                        end else begin
                            job_valid      <= 1'b1;
                            job_ack        <= 1'b1;
                            job_ack_code   <= reply_valid ? reply_ack : r_ack;
                            job_pkt        <= (reply_valid ? reply_kind : r_kind) == 2'd2;
                            job_bc         <= 1'b0;
                            job_hdr_quads  <= 3'd4;
                            job_data_quads <= reply_valid ? reply_data_quads : r_dq;
                        end
                        gstate <= G_SENDING;
                    end else if (waited == REPLY_WAIT) begin
                        // Busy with an earlier packet: ack_busy_X.
                        job_valid      <= 1'b1;
                        job_ack        <= 1'b1;
                        job_ack_code   <= ACK_BUSY_X;
                        job_pkt        <= 1'b0;
                        job_bc         <= 1'b0;
                        job_data_quads <= 10'd0;
                        drop_early     <= 1'b1;
                        gstate         <= G_SENDING;
                    end
                end
                default: begin // G_SENDING: until the interface is released
                    if (tx_done) begin
                        gstate      <= G_IDLE;
                        outstanding <= O_NONE;
                        bc_active   <= 1'b0;
                        if (sending_bc) begin
                            bc_sent      <= 1'b1;
                            bc_wait_drop <= 1'b1;
                        end
                        sending_bc  <= 1'b0;
                    end
                end
            endcase
        end
    end
endmodule

`default_nettype wire
