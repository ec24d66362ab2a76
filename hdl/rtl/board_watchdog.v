// board_watchdog: the board's watchdog (shared/spec/fpga-board.md, sections
// 2 and 7).
//
// Every register write to the board (including the broadcast query and the
// other boards' status broadcasts) refreshes it. With a period of P ticks
// (register 3, bits 15:0; one tick = 256 system clocks, 5.208 us; 0 turns
// it off) it fires at exactly `last write + 256 * P` clocks: `fire` pulses
// once and `timed_out` (STATUS bit 23) stays set until the host enables
// motor power or an amplifier (`clear`). It runs from power-up with the
// power-up period 0x1680 (30 ms).
//
// Writes reach the watchdog a few clocks after the packet that carried them
// ended (their time comes with them), so the expiry is judged EVAL_DELAY
// clocks in the past: a write that ended before the expiry instant always
// counts, as it does in the software board, and the amplifiers go off
// EVAL_DELAY clocks (80 ns) after the exact instant.
`default_nettype none

module board_watchdog #(
    parameter [15:0] POWER_UP_TICKS = 16'h1680, // period after reset
    parameter integer EVAL_DELAY    = 4         // clocks, 1..15
) (
    input  wire        clk,
    input  wire        rst,
    input  wire [31:0] now,           // clocks since reset
    input  wire        refresh,       // a write to the board ...
    input  wire [31:0] refresh_time,  // ... at this clock
    input  wire        set_period,    // register 3 written
    input  wire [15:0] period_in,
    input  wire        clear,         // power or an amplifier enabled
    input  wire        reboot,        // STATUS reboot: back to power-up
    output reg  [15:0] period,
    output reg         timed_out,
    output reg         fire
);
    initial begin
        if (EVAL_DELAY < 1 || EVAL_DELAY > 15) begin
            $display("board_watchdog: EVAL_DELAY must be 1..15");
            $finish;
        end
    end

    reg  [31:0] last_write;
    // now - EVAL_DELAY, kept in a register: `now` counts up by one a clock
    // from 0 after reset.
    reg  [31:0] judged;
    always @(posedge clk)
        judged <= rst ? 32'd0 - EVAL_DELAY : now + 32'd1 - EVAL_DELAY;
    wire [31:0] elapsed = judged - last_write;
    wire [31:0] limit   = {8'd0, period, 8'd0};   // period * 256
    // A write that comes after the expiry instant finds the watchdog fired.
    wire [31:0] gap     = refresh_time - last_write;
    wire        late    = refresh && !gap[31] && gap >= limit;

    always @(posedge clk) begin
        fire <= 1'b0;
        if (rst) begin
            period     <= POWER_UP_TICKS;
            last_write <= 32'd0;
            timed_out  <= 1'b0;
        end else if (reboot) begin
            period     <= POWER_UP_TICKS;
            last_write <= refresh_time;
            timed_out  <= 1'b0;
        end else begin
            if (refresh) last_write <= refresh_time;
            if (set_period) period <= period_in;
            if (period != 16'd0 && !timed_out &&
                (late || (!refresh && !elapsed[31] && elapsed >= limit))) begin
                timed_out <= 1'b1;
                fire      <= 1'b1;
            end
            if (clear) timed_out <= 1'b0;
        end
    end
endmodule

`default_nettype wire
