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

    // One multiplexer per port (always @* so every source is in the
    // sensitivity list).
    reg [31:0] mux_a, mux_b;
    always @* begin
        mux_a = select(index_a, timestamp, status_word, din_word, temp_word, adc_word,
                       pos_word, enc_period, enc_qtr1, enc_qtr5, enc_run, mstat_word);
        mux_b = select(index_b, timestamp, status_word, din_word, temp_word, adc_word,
                       pos_word, enc_period, enc_qtr1, enc_qtr5, enc_run, mstat_word);
    end
    assign data_a = mux_a;
    assign data_b = mux_b;

    function [31:0] select(input [9:0] q, input [31:0] ts, input [31:0] st,
                           input [31:0] din, input [31:0] temp, input [127:0] adcs,
                           input [127:0] pos, input [127:0] per, input [127:0] q1,
                           input [127:0] q5, input [127:0] run, input [127:0] ms);
        begin
            select = 32'd0;
            if (q < 10'd32) begin
                case (q[4:2])
                    3'd0: case (q[1:0])
                              2'd0: select = ts;
                              2'd1: select = st;
                              2'd2: select = din;
                              default: select = temp;
                          endcase
                    3'd1: select = adcs[32*q[1:0] +: 32];
                    3'd2: select = pos[32*q[1:0] +: 32];
                    3'd3: select = per[32*q[1:0] +: 32];
                    3'd4: select = q1[32*q[1:0] +: 32];
                    3'd5: select = q5[32*q[1:0] +: 32];
                    3'd6: select = run[32*q[1:0] +: 32];
                    default: select = ms[32*q[1:0] +: 32];
                endcase
            end
        end
    endfunction
endmodule

`default_nettype wire
