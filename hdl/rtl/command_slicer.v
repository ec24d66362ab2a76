// command_slicer: takes this board's slice of a real-time write to
// address 0 (shared/spec/fpga-board.md, sections 5 and 6.5; Rev 8).
//
// The payload is one board's write block or the host's command block: write
// blocks of several boards concatenated in ascending board order. Each
// block starts with a header quadlet board_id << 8 | quadlets (the header
// counts itself); a QLA1 block is 6 quadlets: header, four DAC words, the
// control word. The slicer walks the headers from the start to the block
// naming BOARD_ID and writes its DAC words to the axis DAC registers, then
// the control word to STATUS with only bits 19:0 taking effect. A walk that
// meets a header of length 0, a block running past the payload, a payload
// that is not whole quadlets, or a block naming this board that is not 6
// quadlets long changes nothing. No block naming the board: nothing.
// The payload sits in the receive buffer (data two clocks after the
// address: its output is registered); writes go out one per clock.
`default_nettype none

module command_slicer #(
    parameter [3:0] BOARD_ID = 4'd0
) (
    input  wire        clk,
    input  wire        rst,
    input  wire        start,
    input  wire [15:0] length,       // payload bytes
    input  wire [31:0] time_in,
    output reg         busy,
    // Payload read port.
    output reg  [8:0]  rd_addr,
    input  wire [31:0] rd_data,
    // Register writes.
    output reg         wr_en,
    output reg  [15:0] wr_addr,
    output reg  [31:0] wr_data,
    output reg  [31:0] wr_time
);
    localparam [7:0] BLOCK_QUADLETS = 8'd6;
    localparam [2:0] S_IDLE = 3'd0, S_WAIT1 = 3'd1, S_HEAD = 3'd2,
                     S_WAIT2 = 3'd3, S_APPLY = 3'd4, S_LATCH = 3'd5,
                     S_WAIT1B = 3'd6, S_WAIT2B = 3'd7;

    reg [2:0]  state;
    reg [10:0] pos;        // quadlet of the current header
    reg [10:0] total;      // payload quadlets
    reg [3:0]  j;          // quadlet of our block being applied (1..5)
    // The header, registered before it is looked at (the walk's decisions
    // take a clock of their own).
    reg [15:0] head;

    wire [7:0]  h_quads = head[7:0];
    wire [7:0]  h_board = head[15:8];
    wire [11:0] h_end   = {1'b0, pos} + {4'd0, h_quads};

    always @(posedge clk) begin
        wr_en <= 1'b0;
        if (rst) begin
            state   <= S_IDLE;
            busy    <= 1'b0;
            rd_addr <= 9'd0;
            pos     <= 11'd0;
            total   <= 11'd0;
            j       <= 4'd0;
            head    <= 16'd0;
            wr_addr <= 16'd0;
            wr_data <= 32'd0;
            wr_time <= 32'd0;
        end else begin
            case (state)
                S_IDLE: if (start) begin
                    wr_time <= time_in;
                    total   <= (length[15:13] != 3'd0) ? 11'h7FF : length[12:2];
                    pos     <= 11'd0;
                    rd_addr <= 9'd0;
                    if (length[1:0] != 2'd0 || length == 16'd0) begin
                        busy <= 1'b0;
                    end else begin
                        busy  <= 1'b1;
                        state <= S_WAIT1;
                    end
                end
                S_WAIT1:  state <= S_WAIT1B;
                S_WAIT1B: state <= S_LATCH;
                S_LATCH: begin
                    // rd_data is the header at `pos`.
                    head  <= rd_data[15:0];
                    state <= S_HEAD;
                end
                S_HEAD: begin
                    // `head` is the header at `pos`.
                    if (h_quads == 8'd0 || h_end > {1'b0, total}) begin
                        busy  <= 1'b0;
                        state <= S_IDLE;
                    end else if (h_board == {4'd0, BOARD_ID}) begin
                        if (h_quads != BLOCK_QUADLETS) begin
                            busy  <= 1'b0;
                            state <= S_IDLE;
                        end else begin
                            rd_addr <= pos[8:0] + 9'd1;
                            j       <= 4'd1;
                            state   <= S_WAIT2;
                        end
                    end else if (h_end >= {1'b0, total}) begin
                        busy  <= 1'b0;   // walked to the end: not addressed
                        state <= S_IDLE;
                    end else begin
                        pos     <= h_end[10:0];
                        rd_addr <= h_end[8:0];
                        state   <= S_WAIT1;
                    end
                end
                S_WAIT2, S_WAIT2B: begin
                    rd_addr <= rd_addr + 9'd1;
                    state   <= (state == S_WAIT2) ? S_WAIT2B : S_APPLY;
                end
                S_APPLY: begin
                    // rd_data is quadlet j of the block.
                    wr_en <= 1'b1;
                    if (j <= 4'd4) begin
                        wr_addr <= {8'h00, j, 4'h1};          // axis j DAC
                        wr_data <= rd_data;
                    end else begin
                        wr_addr <= 16'h0000;                  // STATUS
                        wr_data <= {12'd0, rd_data[19:0]};
                    end
                    rd_addr <= rd_addr + 9'd1;
                    j       <= j + 4'd1;
                    if (j == 4'd5) begin
                        busy  <= 1'b0;
                        state <= S_IDLE;
                    end
                end
                default: state <= S_IDLE;
            endcase
        end
    end
endmodule

`default_nettype wire
