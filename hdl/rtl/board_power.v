// board_power: motor power, safety relay, amplifier enables and the safety
// checks of a QLA board (shared/spec/fpga-board.md, sections 2, 3 and 7).
//
// Commands arrive one per clock with the clock they belong to:
// - a STATUS command (mask/value pairs: power bits 19/18, relay 17/16,
//   amplifiers 11:8/3:0) applied power first, so one word may switch power
//   and amplifiers on together;
// - a per-axis amplifier request from a Rev 8 DAC word (bits 29:28).
// Asking for an amplifier clears the watchdog flag and the axis's safety
// disable and, with motor power enabled, records when it was asked.
// An amplifier drives its motor from max(request, motor supply good + 40 ms)
// + its enable delay (MOTOR_CONFIG bits 23:16, units of 1024 clocks). The
// motor-supply-good comparator is an input pin. The watchdog's `fire`
// drops every request. The current check: every 100 us (4915.2 clocks, by
// an exact fractional counter) each driving axis compares the measured
// current (ADC bits 15:0) with its effective command; a difference above
// 0.44 A (2306 counts) that lasts 50 ms drops the request and sets the
// axis's safety disable (STATUS bits 7:4, MOTOR_STATUS bit 17).
//
// To keep the arithmetic small, one unit serves the axes in turn: each
// axis's turn-on instant is recomputed every AXES clocks (an axis whose
// request, delay or supply changed is held off until its instant is
// fresh), and the current check runs over the axes one per clock right
// after each tick, with the tick's clock and the amplifier states latched
// at the tick. As in the software board, the check also runs at the
// instant an amplifier turns on.
`default_nettype none

module board_power #(
    parameter integer AXES = 4,                      // amplifiers (QLA1: 4), 1..4
    parameter [31:0]  HOLD_CLOCKS     = 32'd1966080, // supply good to drive: 40 ms
    parameter [31:0]  MISMATCH_CLOCKS = 32'd2457600  // current mismatch to trip: 50 ms
) (
    input  wire            clk,
    input  wire            rst,
    input  wire [31:0]     now,
    // STATUS command.
    input  wire            cmd_valid,
    input  wire [31:0]     cmd_time,
    /* verilator lint_off UNUSEDSIGNAL */
    input  wire [31:0]     cmd_word,      // STATUS write word (reboot handled outside)
    /* verilator lint_on UNUSEDSIGNAL */
    // Amplifier requests from DAC words.
    input  wire [AXES-1:0] amp_req_valid,
    input  wire [AXES-1:0] amp_req_value,
    input  wire [31:0]     amp_req_time,
    input  wire            watchdog_fire,
    input  wire            reboot,
    // Per-axis inputs.
    input  wire [8*AXES-1:0]  enable_delay,  // MOTOR_CONFIG 23:16
    input  wire [AXES-1:0]    delay_written, // MOTOR_CONFIG written this clock
    input  wire [16*AXES-1:0] measured,      // ADC current codes
    input  wire [16*AXES-1:0] command,       // effective DAC commands
    input  wire [AXES-1:0]    check_enable,  // current check on (MOTOR_CONFIG 31 clear, current control)
    // Pins.
    input  wire            supply_present,
    input  wire            supply_good,
    // State.
    output reg             power_enabled,
    output reg             relay,
    output wire            supply_fault,
    output reg  [AXES-1:0] requested,
    output wire [AXES-1:0] amp_on,
    output reg  [AXES-1:0] safety_disabled,
    output wire            clear_watchdog   // power or an amplifier asked on
);
    initial begin
        if (AXES < 1 || AXES > 4) begin
            $display("board_power: AXES must be 1..4");
            $finish;
        end
        if (HOLD_CLOCKS == 32'd0 || MISMATCH_CLOCKS == 32'd0) begin
            $display("board_power: HOLD_CLOCKS and MISMATCH_CLOCKS must not be 0");
            $finish;
        end
    end

    localparam integer LAST = AXES - 1;
    localparam [1:0]  LAST_AXIS = LAST[1:0];
    localparam [2:0]  SCAN_END  = AXES[2:0];
    localparam [15:0] MISMATCH_COUNTS = 16'd2306;     // 0.44 A
    localparam [15:0] TICK_NUM = 16'd5, TICK_DEN = 16'd24576; // 4915.2 clocks

    wire power_mask  = cmd_word[19], power_value = cmd_word[18];
    wire relay_mask  = cmd_word[17], relay_value = cmd_word[16];
    wire [3:0] amp_mask  = cmd_word[11:8];
    wire [3:0] amp_value = cmd_word[3:0];

    // Power after this clock's command: amplifier requests see it.
    wire power_next = (cmd_valid && power_mask) ? power_value : power_enabled;
    wire power_on_cmd = cmd_valid && power_mask && power_value;

    assign supply_fault = power_enabled && !supply_present;

    // The motor supply has been good (while power stays enabled).
    reg        good_seen;
    reg [31:0] req_since [0:AXES-1];
    reg [31:0] on_at [0:AXES-1];
    reg [AXES-1:0] on_fresh;          // on_at is up to date
    reg [31:0] mismatch_since [0:AXES-1];
    reg [AXES-1:0] mismatching;
    reg [15:0] tick_acc;
    reg        tick;
    reg [31:0] tick_time;
    reg [AXES-1:0] tick_on;           // amplifiers driving at the tick
    reg [2:0]  scan;                  // 0: idle, else axis scan - 1 is checked
    reg [1:0]  rr;                    // axis whose turn-on instant is computed
    reg [AXES-1:0] was_on;            // amp_on one clock ago

    reg [AXES-1:0] want_on, want_off;
    reg            any_enable_request;
    integer i;
    always @* begin
        want_on  = {AXES{1'b0}};
        want_off = {AXES{1'b0}};
        for (i = 0; i < AXES; i = i + 1) begin
            if (cmd_valid && amp_mask[i]) begin
                if (amp_value[i]) want_on[i] = 1'b1; else want_off[i] = 1'b1;
            end
            if (amp_req_valid[i]) begin
                if (amp_req_value[i]) want_on[i] = 1'b1; else want_off[i] = 1'b1;
            end
        end
        any_enable_request = (want_on != {AXES{1'b0}});
    end
    assign clear_watchdog = power_on_cmd || any_enable_request;

    // Axes whose turn-on instant goes stale this clock (a new request, a
    // delay written, the supply's state changed): on_fresh clears.
    reg [AXES-1:0] stale;
    always @* begin
        stale = delay_written;
        if (!power_enabled || !supply_good) begin
            if (good_seen) stale = {AXES{1'b1}};
        end else if (!good_seen) begin
            stale = {AXES{1'b1}};
        end
        for (i = 0; i < AXES; i = i + 1)
            if (want_on[i] && power_next &&
                !(requested[i] && !watchdog_fire &&
                  !(cmd_valid && power_mask && !power_value)))
                stale[i] = 1'b1;
    end

    // The turn-on instant of axis rr: max(request, good + hold) + delay,
    // over three clocks: the axis's request and delay are registered (with
    // whether they are still current), then the later of the two instants,
    // then the sum.
    reg [31:0]  allowed;    // supply good since + HOLD_CLOCKS
    wire [1:0]  ax       = (AXES == 1) ? 2'd0 : rr;
    reg  [1:0]  a_ax;
    reg         a_ok;
    reg  [31:0] a_req;
    reg  [7:0]  a_delay;
    wire        a_early  = $signed(a_req - allowed) < 0;
    reg  [1:0]  b_ax;
    reg         b_ok;
    reg  [31:0] b_from;
    reg  [7:0]  b_delay;
    wire [31:0] b_on_at  = b_from + {14'd0, b_delay, 10'd0};
    always @(posedge clk) begin
        a_ax    <= ax;
        a_ok    <= !stale[ax] && !rst && !reboot;
        a_req   <= req_since[ax];
        a_delay <= enable_delay[8*ax +: 8];
        b_ax    <= a_ax;
        b_ok    <= a_ok && !stale[a_ax] && !rst && !reboot;
        b_from  <= a_early ? allowed : a_req;
        b_delay <= a_delay;
    end

    // Whether each axis's instant has come, registered (`now` counts up by
    // one a clock): it is valid once on_at has been fresh for a clock, so an
    // instant already past when it is first worked out turns the amplifier
    // on a clock after that; one still ahead turns it on at that clock.
    reg [AXES-1:0] reached, fresh_held;
    genvar g;
    generate
        for (g = 0; g < AXES; g = g + 1) begin : axis
            always @(posedge clk) begin
                reached[g]    <= $signed(now + 32'd1 - on_at[g]) >= 0;
                fresh_held[g] <= on_fresh[g];
            end
            assign amp_on[g] = requested[g] && power_enabled && good_seen &&
                               on_fresh[g] && fresh_held[g] && reached[g];
        end
    endgenerate

    // The current check of one axis (scan - 1). Every axis's comparison
    // is registered each clock (the measured current and the command as
    // they were one clock before the axis's turn), and whether its
    // mismatch had lasted long enough at the tick is registered at the
    // tick (only the axis's own turn changes its mismatch_since).
    wire [1:0]     sax = (AXES == 1) ? 2'd0 : scan[1:0] - 2'd1;
    reg [AXES-1:0] over, long_now, long_at_tick;
    generate
        for (g = 0; g < AXES; g = g + 1) begin : check
            wire [15:0] cur = measured[16*g +: 16];
            wire [15:0] cmd = command[16*g +: 16];
            wire [16:0] diff = (cur >= cmd) ? {1'b0, cur} - {1'b0, cmd}
                                            : {1'b0, cmd} - {1'b0, cur};
            always @(posedge clk) over[g] <= diff > {1'b0, MISMATCH_COUNTS};
            always @* long_now[g] = (now - mismatch_since[g]) >= MISMATCH_CLOCKS;
        end
    endgenerate
    wire        m_over   = over[sax];
    wire        m_long   = long_at_tick[sax];

    always @(posedge clk) begin
        if (rst || reboot) begin
            power_enabled   <= 1'b0;
            relay           <= 1'b0;
            requested       <= {AXES{1'b0}};
            safety_disabled <= {AXES{1'b0}};
            mismatching     <= {AXES{1'b0}};
            on_fresh        <= {AXES{1'b0}};
            good_seen       <= 1'b0;
            allowed         <= HOLD_CLOCKS;
            tick_acc        <= 16'd0;
            tick            <= 1'b0;
            tick_time       <= 32'd0;
            tick_on         <= {AXES{1'b0}};
            long_at_tick    <= {AXES{1'b0}};
            scan            <= 3'd0;
            rr              <= 2'd0;
            was_on          <= {AXES{1'b0}};
            for (i = 0; i < AXES; i = i + 1) begin
                req_since[i]      <= 32'd0;
                on_at[i]          <= 32'd0;
                mismatch_since[i] <= 32'd0;
            end
        end else begin
            // One axis's turn-on instant per clock.
            on_at[b_ax] <= b_on_at;
            rr <= (rr == LAST_AXIS) ? 2'd0 : rr + 2'd1;
            on_fresh <= (on_fresh | ({{(AXES-1){1'b0}}, b_ok} << b_ax)) & ~stale;
            // The safety tick: a clock whose count crossed k * 4915.2.
            if (tick_acc + TICK_NUM >= TICK_DEN) begin
                tick_acc <= tick_acc + TICK_NUM - TICK_DEN;
                tick     <= 1'b1;
            end else begin
                tick_acc <= tick_acc + TICK_NUM;
                tick     <= 1'b0;
            end
            // Motor supply good, while power is enabled.
            if (!power_enabled || !supply_good) begin
                if (good_seen) on_fresh <= {AXES{1'b0}};
                good_seen <= 1'b0;
            end else if (!good_seen) begin
                good_seen  <= 1'b1;
                allowed    <= now + HOLD_CLOCKS;
                on_fresh   <= {AXES{1'b0}};
            end
            // The watchdog drops every request first.
            if (watchdog_fire) requested <= {AXES{1'b0}};
            // The current check, one axis per clock after the tick (or after
            // an amplifier turned on).
            was_on <= amp_on;
            if (tick || (amp_on & ~was_on) != {AXES{1'b0}}) begin
                tick_time    <= now;
                tick_on      <= amp_on;
                long_at_tick <= long_now;
                scan      <= 3'd1;
            end else if (scan != 3'd0) begin
                if (!tick_on[sax] || !m_over || !check_enable[sax]) begin
                    mismatching[sax] <= 1'b0;
                end else if (!mismatching[sax]) begin
                    mismatching[sax]    <= 1'b1;
                    mismatch_since[sax] <= tick_time;
                end else if (m_long) begin
                    requested[sax]       <= 1'b0;
                    safety_disabled[sax] <= 1'b1;
                    mismatching[sax]     <= 1'b0;
                end
                scan <= (scan == SCAN_END) ? 3'd0 : scan + 3'd1;
            end
            // STATUS command: power first, then relay, then amplifiers.
            if (cmd_valid && power_mask) begin
                power_enabled <= power_value;
                if (power_value) begin
                    safety_disabled <= {AXES{1'b0}};
                    mismatching     <= {AXES{1'b0}};
                end else begin
                    requested <= {AXES{1'b0}};
                end
            end
            if (cmd_valid && relay_mask) relay <= relay_value;
            for (i = 0; i < AXES; i = i + 1) begin
                if (want_on[i]) begin
                    safety_disabled[i] <= 1'b0;
                    mismatching[i]     <= 1'b0;
                    if (power_next && !(requested[i] && !watchdog_fire &&
                                        !(cmd_valid && power_mask && !power_value))) begin
                        requested[i] <= 1'b1;
                        req_since[i] <= cmd_valid ? cmd_time : amp_req_time;
                        on_fresh[i]  <= 1'b0;
                    end
                end else if (want_off[i]) begin
                    requested[i] <= 1'b0;
                end
            end
        end
    end
endmodule

`default_nettype wire
