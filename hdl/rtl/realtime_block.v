// realtime_block: the QLA1 real-time read block at firmware Rev 8
// (shared/spec/fpga-board.md, section 4): 32 quadlets
//   0 timestamp (clocks since the previous sample), 1 STATUS,
//   2 DIGITAL_IN, 3 TEMPERATURE, 4-7 ADC, 8-11 ENC_POSITION,
//   12-15 ENC_PERIOD, 16-19 ENC_QTR1, 20-23 ENC_QTR5, 24-27 ENC_RUN,
//   28-31 MOTOR_STATUS; quadlets beyond read 0.
// Every quadlet but the timestamp is a register of the register file, so
// this module keeps the timestamp and maps a quadlet index to the register
// address to read (two indices: the read response and the status-broadcast
// snapshot). A sample (a block read of address 0, or a broadcast query)
// latches the timestamp and restarts it.
`default_nettype none

module realtime_block (
    input  wire         clk,
    input  wire         rst,
    input  wire         sample,          // take a sample ...
    input  wire [31:0]  sample_time,     // ... at this clock
    input  wire         restart,         // reboot: the timestamp restarts
    input  wire [31:0]  restart_time,
    output reg  [31:0]  timestamp,       // of the last sample
    input  wire [9:0]   index_a,
    output wire [15:0]  addr_a,          // register to read for it
    output wire         stamp_a,         // it is the timestamp
    output wire         zero_a,          // it reads 0
    output wire [31:0]  extra_a,         // OR'ed into the register word
    input  wire [9:0]   index_b,
    output wire [15:0]  addr_b,
    output wire         stamp_b,
    output wire         zero_b,
    output wire [31:0]  extra_b
);
    // The temperature quadlet (3) carries the data buffer's status in bits
    // 31:16 during a real-time read (Rev 8 QLA.v, DataBuffer.v): not
    // collecting, channel 1, address 0.
    localparam [31:0] DATABUF_STATUS = 32'h0400_0000;
    reg [31:0] last_sample;

    always @(posedge clk) begin
        if (rst) begin
            last_sample <= 32'd0;
            timestamp   <= 32'd0;
        end else if (restart) begin
            last_sample <= restart_time;
        end else if (sample) begin
            timestamp   <= sample_time - last_sample;
            last_sample <= sample_time;
        end
    end

    // Quadlet index -> register address (channel 0 board, 1..4 axes).
    function [15:0] address(input [4:0] q);
        reg [3:0] axis;
        begin
            axis = {2'b00, q[1:0]} + 4'd1;
            case (q[4:2])
                3'd0: case (q[1:0])
                          2'd1:    address = 16'h0000;   // STATUS
                          2'd2:    address = 16'h000A;   // DIGITAL_IN
                          default: address = 16'h0005;   // TEMPERATURE (0: timestamp)
                      endcase
                3'd1: address = {8'h00, axis, 4'h0};     // ADC
                3'd2: address = {8'h00, axis, 4'h5};     // ENC_POSITION
                3'd3: address = {8'h00, axis, 4'h6};     // ENC_PERIOD
                3'd4: address = {8'h00, axis, 4'h7};     // ENC_QTR1
                3'd5: address = {8'h00, axis, 4'h9};     // ENC_QTR5
                3'd6: address = {8'h00, axis, 4'hA};     // ENC_RUN
                default: address = {8'h00, axis, 4'hC};  // MOTOR_STATUS
            endcase
        end
    endfunction

    assign addr_a  = address(index_a[4:0]);
    assign stamp_a = (index_a == 10'd0);
    assign zero_a  = (index_a >= 10'd32);
    assign extra_a = (index_a == 10'd3) ? DATABUF_STATUS : 32'd0;
    assign addr_b  = address(index_b[4:0]);
    assign stamp_b = (index_b == 10'd0);
    assign zero_b  = (index_b >= 10'd32);
    assign extra_b = (index_b == 10'd3) ? DATABUF_STATUS : 32'd0;
endmodule

`default_nettype wire
