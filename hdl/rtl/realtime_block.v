// realtime_block: the QLA1 real-time read block at firmware Rev 8
// (shared/spec/fpga-board.md, section 4): 32 quadlets
//   0 timestamp (clocks since the previous sample), 1 STATUS,
//   2 DIGITAL_IN, 3 TEMPERATURE, 4-7 ADC, 8-11 ENC_POSITION,
//   12-15 ENC_PERIOD, 16-19 ENC_QTR1, 20-23 ENC_QTR5, 24-27 ENC_RUN,
//   28-31 MOTOR_STATUS; quadlets beyond read 0.
// A sample (a block read of address 0, or a broadcast query) latches the
// timestamp and restarts it. Two independent read ports: one for read
// responses, one for the status-broadcast snapshot.
`default_nettype none

module realtime_block (
    input  wire         clk,
    input  wire         rst,
    input  wire         sample,          // take a sample ...
    input  wire [31:0]  sample_time,     // ... at this clock
    input  wire         restart,         // reboot: the timestamp restarts
    input  wire [31:0]  restart_time,
    input  wire [31:0]  status_word,
    input  wire [31:0]  din_word,
    input  wire [31:0]  temp_word,
    input  wire [127:0] adc_word,
    input  wire [127:0] pos_word,
    input  wire [127:0] enc_period,
    input  wire [127:0] enc_qtr1,
    input  wire [127:0] enc_qtr5,
    input  wire [127:0] enc_run,
    input  wire [127:0] mstat_word,
    input  wire [9:0]   index_a,
    output wire [31:0]  data_a,
    input  wire [9:0]   index_b,
    output wire [31:0]  data_b
);
    reg [31:0] last_sample;
    reg [31:0] timestamp;       // of the last sample

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

    function [31:0] word(input [9:0] q);
        begin
            word = 32'd0;
            if (q < 10'd32) begin
                case (q[4:2])
                    3'd0: case (q[1:0])
                              2'd0: word = timestamp;
                              2'd1: word = status_word;
                              2'd2: word = din_word;
                              default: word = temp_word;
                          endcase
                    3'd1: word = adc_word[32*q[1:0] +: 32];
                    3'd2: word = pos_word[32*q[1:0] +: 32];
                    3'd3: word = enc_period[32*q[1:0] +: 32];
                    3'd4: word = enc_qtr1[32*q[1:0] +: 32];
                    3'd5: word = enc_qtr5[32*q[1:0] +: 32];
                    3'd6: word = enc_run[32*q[1:0] +: 32];
                    default: word = mstat_word[32*q[1:0] +: 32];
                endcase
            end
        end
    endfunction

    assign data_a = word(index_a);
    assign data_b = word(index_b);
endmodule

`default_nettype wire
