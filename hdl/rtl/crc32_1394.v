// crc32_1394: one step of the IEEE 1394 CRC-32 (header CRC and data CRC).
//
// Facts (shared/spec/ieee1394.md, "CRC"): generator 0x04C11DB7, bits taken
// most significant first in wire order, register preset to 0xFFFFFFFF, the
// result transmitted complemented; not reflected (CRC-32/BZIP2).
//
// The module is purely combinational: it advances the CRC register
// `crc_in` over 2, 4 or 8 data bits in one step (the bits a PHY delivers per
// 49.152 MHz clock at S100, S200 and S400). The data bits are always the
// most significant ones of `data` (D[7:6], D[7:4] or D[7:0]), earliest bit
// in the highest position. The loop unrolls into one XOR network per width;
// `width` picks which result leaves the module. The caller keeps the
// register and complements it to form the CRC quadlet.
`default_nettype none

module crc32_1394 (
    input  wire [31:0] crc_in,   // CRC register before this step
    input  wire [7:0]  data,     // data bits, earliest in bit 7
    input  wire [1:0]  width,    // 0: 2 bits, 1: 4 bits, 2 or 3: 8 bits
    output reg  [31:0] crc_out   // CRC register after this step
);
    localparam [31:0] POLY = 32'h04C1_1DB7;

    // The register after the first k data bits, for k = 1..8.
    reg [31:0] after [0:8];
    integer k;
    always @* begin
        after[0] = crc_in;
        for (k = 0; k < 8; k = k + 1) begin
            after[k+1] = {after[k][30:0], 1'b0}
                         ^ ((after[k][31] ^ data[7-k]) ? POLY : 32'h0);
        end
        case (width)
            2'd0:    crc_out = after[2];
            2'd1:    crc_out = after[4];
            default: crc_out = after[8];
        endcase
    end
endmodule

`default_nettype wire
