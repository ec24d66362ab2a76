// sdp_ram: simple dual-port RAM, one write port and one registered read
// port on the same clock (maps onto iCE40 EBR / any FPGA block RAM).
//
// Read data appears one clock after the address (read-first: a read of the
// address written in the same clock returns the old word), or two with
// OUT_REG = 1: the block RAM's output is registered once more, so that no
// logic follows its slow clock-to-output in the same clock.
`default_nettype none

module sdp_ram #(
    parameter integer WIDTH = 32,   // bits per word, >= 1
    parameter integer DEPTH = 512,  // words, a power of two >= 2
    parameter integer ADDR_BITS = 9, // log2(DEPTH)
    parameter integer OUT_REG = 0    // 1: a second read register
) (
    input  wire                 clk,
    input  wire                 wr_en,
    input  wire [ADDR_BITS-1:0] wr_addr,
    input  wire [WIDTH-1:0]     wr_data,
    input  wire [ADDR_BITS-1:0] rd_addr,
    output reg  [WIDTH-1:0]     rd_data
);
    // Elaboration-time checks of the parameters.
    initial begin
        if (WIDTH < 1) begin
            $display("sdp_ram: WIDTH must be at least 1");
            $finish;
        end
        if (OUT_REG != 0 && OUT_REG != 1) begin
            $display("sdp_ram: OUT_REG must be 0 or 1");
            $finish;
        end
        if ((1 << ADDR_BITS) != DEPTH) begin
            $display("sdp_ram: DEPTH must be 2**ADDR_BITS");
            $finish;
        end
    end

    reg [WIDTH-1:0] mem [0:DEPTH-1];

    // Defined contents at power-up (block RAM initialises to zero).
    integer i;
    initial begin
        for (i = 0; i < DEPTH; i = i + 1) mem[i] = {WIDTH{1'b0}};
    end

    reg [WIDTH-1:0] ram_data;
    always @(posedge clk) begin
        if (wr_en) mem[wr_addr] <= wr_data;
        ram_data <= mem[rd_addr];
    end
    generate
        if (OUT_REG == 1) begin : out_reg
            always @(posedge clk) rd_data <= ram_data;
        end else begin : no_out_reg
            always @(*) rd_data = ram_data;
        end
    endgenerate
endmodule

`default_nettype wire
